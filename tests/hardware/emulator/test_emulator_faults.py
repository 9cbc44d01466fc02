"""Each fault kind, scripted in chain time, as the stock SDK and the raw wire see it."""

from __future__ import annotations

import pytest
from servoface.hardware.emulator import EmulatorConfigError, ServoChain, build_instruction
from servoface.hardware.emulator.packet import PacketReceiver

from tests.hardware.emulator.helpers import quick_chain, sdk_port, transact

COMM_SUCCESS, COMM_RX_TIMEOUT, COMM_RX_CORRUPT = 0, -3001, -3002


def fast_sdk(chain: ServoChain):  # type: ignore[no-untyped-def]
    import dynamixel_sdk.port_handler as ph_mod

    port, ph = sdk_port(chain)
    return port, ph, ph_mod


def test_no_reply_scripted_window() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    chain.faults.inject(2, "no_reply", start_s=1.0, duration_s=0.5)
    assert len(transact(ser, 2, 0x01)) == 1
    chain.advance(1.1)
    assert transact(ser, 2, 0x01) == []
    assert len(transact(ser, 1, 0x01)) == 1  # other servos unaffected
    transact(ser, 2, 0x03, b"\x41\x00\x01")  # still hears and acts
    assert chain.servo(2).read_register("LED") == 1
    chain.advance(0.5)
    assert len(transact(ser, 2, 0x01)) == 1


def test_late_reply_adds_delay() -> None:
    chain = ServoChain.create(ids=[1], wire_time=False, clock="manual")
    ser = chain.open_serial()
    chain.faults.inject(1, "late_reply", delay_s=0.02)
    ser.write(build_instruction(1, 0x01))
    assert ser.read(100) == b""
    chain.advance(0.019)
    assert ser.read(100) == b""
    chain.advance(0.002)
    assert len(ser.read(100)) == 14


def test_corrupt_crc_seen_by_sdk_as_rx_corrupt() -> None:
    chain = ServoChain.create(ids=[1], wire_time=False)
    port, ph = sdk_port(chain)
    chain.faults.inject_now(1, "corrupt_crc")
    _, comm, _ = ph.ping(port, 1)
    assert comm == COMM_RX_CORRUPT
    chain.faults.clear(1)
    assert ph.ping(port, 1)[1] == COMM_SUCCESS


def test_dropped_bytes_make_a_short_packet() -> None:
    chain, ser = quick_chain(ids=[1])
    chain.faults.inject(1, "dropped_bytes", drop_bytes=2)
    ser.write(build_instruction(1, 0x02, b"\x84\x00\x04\x00"))
    raw = ser.read(100)
    assert len(raw) == 15 - 2
    assert PacketReceiver().feed(raw) == []  # incomplete: the host would time out with RX corrupt


@pytest.mark.parametrize(
    ("kind", "bit", "drops_torque"),
    [
        ("overload", 0x20, True),
        ("overheating", 0x04, True),
        ("electrical_shock", 0x10, True),
        ("encoder", 0x08, False),
        ("input_voltage", 0x01, True),
    ],
)
def test_hardware_error_bits(kind: str, bit: int, drops_torque: bool) -> None:
    chain, ser = quick_chain(ids=[1])  # XL330: Shutdown 0x35
    servo = chain.servo(1)
    servo.write_register("Torque Enable", 1)
    chain.faults.inject(1, kind, start_s=0.5, duration_s=0.1)
    chain.advance(0.4)
    assert servo.read_register("Hardware Error Status") == 0
    chain.advance(0.2)
    assert servo.read_register("Hardware Error Status") == bit
    assert servo.read_register("Torque Enable") == (0 if drops_torque else 1)
    assert transact(ser, 1, 0x01)[0].error == 0x80
    chain.advance(1.0)
    assert servo.read_register("Hardware Error Status") == bit  # latched after the cause has gone
    transact(ser, 1, 0x08)
    chain.advance(0.2)
    assert servo.read_register("Hardware Error Status") == 0


def test_disconnect_and_reconnect() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    servo = chain.servo(1)
    servo.write_register("Return Delay Time", 10)  # EEPROM survives
    servo.write_register("LED", 1)  # RAM does not
    servo.write_register("Torque Enable", 1)
    chain.faults.inject(1, "disconnect", start_s=1.0, duration_s=2.0)
    chain.advance(1.5)
    assert transact(ser, 1, 0x01) == []
    transact(ser, 1, 0x03, b"\x41\x00\x00")  # not heard
    assert servo.read_register("Torque Enable") == 0  # no power
    chain.advance(1.6)
    (st,) = transact(ser, 1, 0x01)
    assert st.id == 1
    assert servo.read_register("LED") == 0 and servo.read_register("Return Delay Time") == 10


def test_sync_read_fails_whole_group_when_one_is_silent() -> None:
    import dynamixel_sdk as sdk

    chain = ServoChain.create(ids=[1, 2, 3], wire_time=False)
    port, ph = sdk_port(chain)
    group = sdk.GroupSyncRead(port, ph, 132, 4)
    for sid in (1, 2, 3):
        group.addParam(sid)
    assert group.txRxPacket() == COMM_SUCCESS
    chain.faults.inject_now(2, "no_reply")
    assert group.txRxPacket() == COMM_RX_TIMEOUT
    assert group.fastSyncRead() in (COMM_RX_TIMEOUT, COMM_RX_CORRUPT)


def test_bad_fault_descriptions_rejected() -> None:
    chain, _ = quick_chain(ids=[1])
    with pytest.raises(EmulatorConfigError, match="fault kind"):
        chain.faults.inject(1, "gremlins")
    with pytest.raises(EmulatorConfigError, match="no such servo"):
        chain.faults.inject(9, "no_reply")
    with pytest.raises(EmulatorConfigError, match="duration"):
        chain.faults.inject(1, "no_reply", duration_s=-1)
    assert chain.faults.all() == []
