"""Control-table details checked on the wire against the e-manual model pages (cited per test).

Pages: e-manual "XL330-M288-T", "XL430-W250-T", "XM430-W350-T/R", "MX-28(2.0)" control tables, the shared
sections "Drive Mode(10)", "Protocol Type(13)", "Startup Configuration(60)", "Indirect Address", and
"DYNAMIXEL Protocol 2.0" (Status Packet error field, Control Table Backup).
"""

from __future__ import annotations

import pytest
from servoface.hardware.emulator import Instruction as I
from servoface.hardware.emulator.packet import BROADCAST_ID, ErrorNumber

from tests.hardware.emulator.helpers import le, quick_chain, sdk_port, transact

X_SERIES = ["XL330-M288", "XL430-W250", "XM430-W350"]


def _write(ser, addr: int, value: int, size: int = 1) -> int:  # type: ignore[no-untyped-def]
    (st,) = transact(ser, 1, I.WRITE, le(addr, 2) + le(value, size))
    return st.error


def _read(ser, addr: int, size: int) -> tuple[int, bytes]:  # type: ignore[no-untyped-def]
    (st,) = transact(ser, 1, I.READ, le(addr, 2) + le(size, 2))
    return st.error, st.data


@pytest.mark.parametrize("model", X_SERIES)
def test_startup_configuration_exists_with_range_0_to_3(model: str) -> None:
    """e-manual XL330-M288 / XL430-W250 / XM430-W350, Startup Configuration(60): RW, initial 0, range 0~3
    (bit 0 Startup Torque On, bit 1 RAM Restore; firmware V45, XL330 V46, below what we report)."""
    _, ser = quick_chain(ids=[1], model=model)
    assert _read(ser, 60, 1) == (0, b"\x00")
    assert _write(ser, 60, 3) == 0
    assert _read(ser, 60, 1) == (0, b"\x03")
    assert _write(ser, 60, 4) == ErrorNumber.DATA_RANGE


def test_startup_torque_on_after_reboot() -> None:
    """e-manual Startup Configuration(60), bit 0: on boot the servo is Torque On."""
    chain, ser = quick_chain(ids=[1])
    assert _write(ser, 60, 1) == 0
    (st,) = transact(ser, 1, I.REBOOT)
    assert st.error == 0
    chain.advance(0.2)
    assert _read(ser, 64, 1) == (0, b"\x01")


def test_ram_restore_brings_back_the_backed_up_gains() -> None:
    """e-manual Protocol 2.0, Control Table Backup (P1 0x01 'CTRL', torque off) and Startup
    Configuration(60) bit 1 RAM Restore: after a reboot the gains come from the backup, not the defaults."""
    chain, ser = quick_chain(ids=[1])
    assert _write(ser, 84, 1234, 2) == 0  # Position P Gain
    assert _write(ser, 60, 2) == 0
    (st,) = transact(ser, 1, I.CONTROL_TABLE_BACKUP, b"\x01CTRL")
    assert st.error == 0
    assert _read(ser, 147, 1) == (0, b"\x01")  # Backup Ready
    (st,) = transact(ser, 1, I.REBOOT)
    chain.advance(0.2)
    assert _read(ser, 84, 2) == (0, le(1234, 2))
    assert _write(ser, 64, 1) == 0
    (st,) = transact(ser, 1, I.CONTROL_TABLE_BACKUP, b"\x01CTRL")
    assert st.error == ErrorNumber.ACCESS  # only with torque off
    (st,) = transact(ser, 1, I.CONTROL_TABLE_BACKUP, b"\x07CTRL")
    assert st.error == ErrorNumber.DATA_RANGE


DRIVE_MODE_TOP = [("XL330-M288", 13), ("XL430-W250", 13), ("XM430-W350", 13), ("MX-28(2.0)", 5)]


@pytest.mark.parametrize(("model", "top"), DRIVE_MODE_TOP)
def test_drive_mode_range_per_model(model: str, top: int) -> None:
    """e-manual Drive Mode(10): X-series bits 0 (reverse), 2 (time-based profile), 3 (Torque On by Goal
    Update, XL330 from V46, X430 from V45) -> 0~13; MX-28(2.0) has bits 0 and 2 only -> 0~5."""
    _, ser = quick_chain(ids=[1], model=model)
    assert _write(ser, 10, top) == 0
    assert _write(ser, 10, top + 1) == ErrorNumber.DATA_RANGE
    assert _write(ser, 10, 15) == ErrorNumber.DATA_RANGE


def test_torque_on_by_goal_update() -> None:
    """e-manual Drive Mode(10) bit 3: with Torque Enable 0 a goal write switches torque on and runs."""
    chain, ser = quick_chain(ids=[1])
    assert _write(ser, 10, 8) == 0
    assert _write(ser, 116, 2500, 4) == 0
    assert _read(ser, 64, 1) == (0, b"\x01")
    chain.advance(1.0)
    assert abs(chain.servo(1).position_tick - 2500) <= 2


@pytest.mark.parametrize(
    ("model", "good", "bad"),
    [("XL330-M288", (2, 20, 21, 22), (1, 3, 19, 23)), ("XL430-W250", (1, 2), (0, 3, 22))],
)
def test_protocol_type_values(model: str, good: tuple[int, ...], bad: tuple[int, ...]) -> None:
    """e-manual Protocol Type(13): XL330 defines 2 (Protocol 2.0), 20 (S.BUS), 21 (iBUS), 22 (RC-PWM);
    XL430 defines 1 and 2. Undefined values get Data Range Error."""
    _, ser = quick_chain(ids=[1], model=model)
    for v in bad:
        assert _write(ser, 13, v) == ErrorNumber.DATA_RANGE, v
    for v in good:
        assert _write(ser, 13, v) == 0, v
    assert _write(ser, 13, 2) == 0


@pytest.mark.parametrize(("model", "top"), [("XL330-M288", 227), ("XL430-W250", 661), ("XM430-W350", 661)])
def test_indirect_address_range(model: str, top: int) -> None:
    """e-manual Indirect Address: XL330-M288 range 64~227 (its table ends at Indirect Data 20, 227);
    XL430-W250 / XM430-W350 64~661."""
    _, ser = quick_chain(ids=[1], model=model)
    assert _write(ser, 168, top, 2) == 0
    assert _write(ser, 168, top + 1, 2) == ErrorNumber.DATA_RANGE
    assert _write(ser, 168, 63, 2) == ErrorNumber.DATA_RANGE


def test_mx28_velocity_limit_default() -> None:
    """e-manual MX-28(2.0) control table: Velocity Limit(44) initial value 230."""
    chain, ser = quick_chain(ids=[1], model="MX-28(2.0)")
    assert _read(ser, 44, 4) == (0, le(230, 4))


def test_read_past_the_end_is_access_error_with_the_requested_length() -> None:
    """e-manual Protocol 2.0, Status Packet: Access Error for "an address that has not been defined"; the
    Read's status still carries the requested number of data bytes (zeros past the table's end)."""
    chain, ser = quick_chain(ids=[1])  # XL330 table ends at 227
    err, data = _read(ser, 224, 8)
    assert err == ErrorNumber.ACCESS
    assert len(data) == 8 and data[4:] == bytes(4)
    err, data = _read(ser, 300, 4)
    assert (err, data) == (ErrorNumber.ACCESS, bytes(4))


def test_stock_sdk_sync_read_past_the_end_does_not_crash() -> None:
    """The stock SDK's GroupSyncRead.getData on a read past the end returns a value, not IndexError."""
    import dynamixel_sdk as sdk

    chain, _ = quick_chain(ids=[1, 2])
    port, ph = sdk_port(chain)
    group = sdk.GroupSyncRead(port, ph, 226, 4)
    group.addParam(1)
    group.addParam(2)
    assert group.txRxPacket() == sdk.COMM_SUCCESS
    assert group.isAvailable(1, 226, 4)
    assert group.getData(2, 226, 4) == 0
    assert BROADCAST_ID == 0xFE
