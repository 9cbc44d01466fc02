"""Protocol 2.0 behaviour suite: everything ROBOTIS' protocol 2.0 example programs exercise, through the
stock dynamixel-sdk against the emulator, written from the e-manual (not from the examples' code).

Each test names the e-manual section it checks: "DYNAMIXEL Protocol 2.0" > Instruction Details (Ping,
Read, Write, Reg Write/Action, Factory Reset, Reboot, Clear, Sync Read/Write, Bulk Read/Write, Fast Sync
Read, Fast Bulk Read) and the X-series control-table sections (Indirect Address, Operating Mode).
One chain per test, all four models where the behaviour is per model.
"""

from __future__ import annotations

import dynamixel_sdk as sdk
import pytest
from servoface.hardware.emulator import MODELS, ServoChain

from tests.hardware.emulator.helpers import sdk_port

OK = sdk.COMM_SUCCESS
ALL_MODELS = sorted(MODELS)


def _open(ids: list[int], model: str = "XL330-M288", **kw: object):  # type: ignore[no-untyped-def]
    kw.setdefault("wire_time", False)
    kw.setdefault("clock", "manual")
    chain = ServoChain.create(ids=ids, model=model, **kw)  # type: ignore[arg-type]
    port, ph = sdk_port(chain)
    return chain, port, ph


@pytest.mark.parametrize("model", ALL_MODELS)
def test_ping_answers_model_number_and_firmware(model: str) -> None:
    """Protocol 2.0 > Ping: the status carries Model Number (2 bytes) and Firmware Version (1 byte)."""
    chain, port, ph = _open([1], model)
    spec = MODELS[model]
    assert ph.ping(port, 1) == (spec.model_number, OK, 0)
    assert ph.read1ByteTxRx(port, 1, 6) == (spec.firmware_version, OK, 0)
    assert ph.ping(port, 9)[1] == sdk.COMM_RX_TIMEOUT  # no servo 9: silence


def test_broadcast_ping_finds_every_servo_with_model_and_firmware() -> None:
    """Protocol 2.0 > Ping, broadcast ID 0xFE: every device answers in turn (model + firmware)."""
    chain = ServoChain.create(ids=[(1, "XL330-M288"), (4, "XL430-W250"), (9, "MX-28(2.0)")], wire_time=True)
    port, ph = sdk_port(chain)
    found, comm = ph.broadcastPing(port)
    assert comm == OK
    assert found == {1: [1200, 52], 4: [1060, 46], 9: [30, 46]}


@pytest.mark.parametrize("model", ALL_MODELS)
def test_read_write_moves_to_the_goal(model: str) -> None:
    """Protocol 2.0 > Read / Write; Torque Enable(64), Goal Position(116), Present Position(132)."""
    chain, port, ph = _open([1], model)
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (OK, 0)
    for goal in (100, 4000):
        assert ph.write4ByteTxRx(port, 1, 116, goal) == (OK, 0)
        chain.advance(3.0)
        position, comm, err = ph.read4ByteTxRx(port, 1, 132)
        assert (comm, err) == (OK, 0) and abs(position - goal) <= 2
        assert ph.read1ByteTxRx(port, 1, 122) == (0, OK, 0)  # Moving(122): stopped


def test_reg_write_then_action() -> None:
    """Protocol 2.0 > Reg Write holds the write (Registered Instruction(69) = 1) until Action."""
    chain, port, ph = _open([1, 2])
    assert ph.regWriteTxRx(port, 1, 65, 1, [1]) == (OK, 0)
    assert ph.read1ByteTxRx(port, 1, 69) == (1, OK, 0)
    assert ph.read1ByteTxRx(port, 1, 65) == (0, OK, 0)
    assert ph.action(port, sdk.BROADCAST_ID) == OK
    assert ph.read1ByteTxRx(port, 1, 65) == (1, OK, 0)
    assert ph.read1ByteTxRx(port, 1, 69) == (0, OK, 0)


def test_sync_write_and_sync_read() -> None:
    """Protocol 2.0 > Sync Write (no status) and Sync Read (one status per listed ID, in list order)."""
    chain, port, ph = _open([1, 2, 3])
    torque = sdk.GroupSyncWrite(port, ph, 64, 1)
    goals = sdk.GroupSyncWrite(port, ph, 116, 4)
    for sid, goal in ((1, 1000), (2, 2000), (3, 3000)):
        torque.addParam(sid, [1])
        goals.addParam(sid, list(goal.to_bytes(4, "little")))
    assert torque.txPacket() == OK and goals.txPacket() == OK
    chain.advance(3.0)
    read = sdk.GroupSyncRead(port, ph, 132, 4)
    for sid in (3, 1, 2):
        assert read.addParam(sid)
    assert read.txRxPacket() == OK
    for sid, goal in ((1, 1000), (2, 2000), (3, 3000)):
        assert read.isAvailable(sid, 132, 4)
        assert abs(read.getData(sid, 132, 4) - goal) <= 2


def test_bulk_write_and_bulk_read_different_addresses_per_servo() -> None:
    """Protocol 2.0 > Bulk Write / Bulk Read: each ID with its own address and length."""
    chain, port, ph = _open([1, 2])
    write = sdk.GroupBulkWrite(port, ph)
    assert write.addParam(1, 65, 1, [1])  # LED of 1
    assert write.addParam(2, 84, 2, list((900).to_bytes(2, "little")))  # Position P Gain of 2
    assert write.txPacket() == OK
    read = sdk.GroupBulkRead(port, ph)
    assert read.addParam(1, 65, 1) and read.addParam(2, 84, 2)
    assert read.txRxPacket() == OK
    assert read.getData(1, 65, 1) == 1 and read.getData(2, 84, 2) == 900


def test_fast_sync_read_and_fast_bulk_read() -> None:
    """Protocol 2.0 > Fast Sync Read / Fast Bulk Read: one combined status packet, ID 0xFE."""
    chain, port, ph = _open([1, 2, 3])
    for sid in (1, 2, 3):
        chain.servo(sid).move_by_hand(500 * sid)
    fast = sdk.GroupSyncRead(port, ph, 132, 4)
    for sid in (1, 2, 3):
        fast.addParam(sid)
    assert fast.fastSyncRead() == OK
    assert [fast.getData(sid, 132, 4) for sid in (1, 2, 3)] == [500, 1000, 1500]
    bulk = sdk.GroupBulkRead(port, ph)
    assert bulk.addParam(1, 132, 4) and bulk.addParam(3, 146, 1)
    assert bulk.fastBulkRead() == OK
    assert bulk.getData(1, 132, 4) == 500 and bulk.getData(3, 146, 1) == 25


@pytest.mark.parametrize(("model", "data_address"), [("XL330-M288", 208), ("XL430-W250", 224), ("MX-28(2.0)", 224)])
def test_indirect_address_maps_registers_into_one_block(model: str, data_address: int) -> None:
    """Indirect Address / Indirect Data: Indirect Address n holds the address Indirect Data n stands for;
    writes and reads of the data block act on the mapped registers (X-series / MX(2.0) control tables)."""
    chain, port, ph = _open([1], model)
    mapped = [116, 117, 118, 119, 65, 132, 133, 134, 135]  # Goal Position, LED, Present Position
    for i, target in enumerate(mapped):
        assert ph.write2ByteTxRx(port, 1, 168 + 2 * i, target) == (OK, 0)
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (OK, 0)
    assert ph.writeTxRx(port, 1, data_address, 5, list((2500).to_bytes(4, "little")) + [1]) == (OK, 0)
    chain.advance(3.0)
    assert ph.read1ByteTxRx(port, 1, 65) == (1, OK, 0)
    data, comm, err = ph.readTxRx(port, 1, data_address + 5, 4)
    assert (comm, err) == (OK, 0) and abs(int.from_bytes(bytes(data), "little") - 2500) <= 2


def test_reboot_turns_torque_off_and_the_servo_comes_back() -> None:
    """Protocol 2.0 > Reboot: status first, then the device restarts (RAM to defaults, torque off)."""
    chain, port, ph = _open([1])
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (OK, 0)
    assert ph.write1ByteTxRx(port, 1, 65, 1) == (OK, 0)
    assert ph.reboot(port, 1) == (OK, 0)
    assert ph.ping(port, 1)[1] == sdk.COMM_RX_TIMEOUT  # still booting
    chain.advance(0.5)
    assert ph.ping(port, 1)[1] == OK
    assert ph.read1ByteTxRx(port, 1, 64) == (0, OK, 0) and ph.read1ByteTxRx(port, 1, 65) == (0, OK, 0)


@pytest.mark.parametrize(
    ("option", "keeps_id", "keeps_baud"), [(0x02, True, True), (0x01, True, False), (0xFF, False, False)]
)
def test_factory_reset_options(option: int, keeps_id: bool, keeps_baud: bool) -> None:
    """Protocol 2.0 > Factory Reset: 0xFF resets all (ID 1, 57 600 bps), 0x01 all but ID, 0x02 all but ID
    and Baud Rate."""
    chain = ServoChain.create(ids=[7], baud=1_000_000, wire_time=False, clock="manual")
    port, ph = sdk_port(chain)
    assert ph.write1ByteTxRx(port, 7, 31, 50) == (OK, 0)  # Temperature Limit
    assert ph.factoryReset(port, 7, option) == (OK, 0)
    servo = chain.servo(7)
    assert servo.read_register("Temperature Limit") == 70
    assert servo.id == (7 if keeps_id else 1)
    assert servo.baud_bps == (1_000_000 if keeps_baud else 57_600)


def test_clear_multi_turn_in_extended_position_mode() -> None:
    """Protocol 2.0 > Clear: Present Position back into one turn once the servo has stopped."""
    chain, port, ph = _open([1])
    assert ph.write1ByteTxRx(port, 1, 11, 4) == (OK, 0)  # Extended Position Control Mode
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (OK, 0)
    assert ph.write4ByteTxRx(port, 1, 116, 3 * 4096 + 500) == (OK, 0)
    chain.advance(5.0)
    assert ph.clearMultiTurn(port, 1) == (OK, 0)
    position, comm, _ = ph.read4ByteTxRx(port, 1, 132)
    assert comm == OK and abs(position - 500) <= 2


def test_two_ports_two_chains() -> None:
    """Multi-port: each port reaches only its own chain (the same id on both is two servos)."""
    a, port_a, ph = _open([1])
    b, port_b, _ = _open([1, 2])
    assert ph.write1ByteTxRx(port_a, 1, 65, 1) == (OK, 0)
    assert ph.read1ByteTxRx(port_b, 1, 65) == (0, OK, 0)
    assert ph.ping(port_a, 2)[1] == sdk.COMM_RX_TIMEOUT and ph.ping(port_b, 2)[1] == OK
    assert a.servo(1).read_register("LED") == 1 and b.servo(1).read_register("LED") == 0


def test_over_the_pty_with_wire_time() -> None:
    """The same calls over a pseudo-terminal with wire time on (the way ROBOTIS' programs open a port)."""
    chain = ServoChain.create(ids=[1, 2], baud=1_000_000)
    path = chain.serve_pty()
    port = sdk.PortHandler(path)
    try:
        assert port.openPort() and port.setBaudRate(1_000_000)
        ph = sdk.PacketHandler(2.0)
        assert ph.ping(port, 2) == (1200, OK, 0)
        assert ph.write1ByteTxRx(port, 2, 65, 1) == (OK, 0)
        read = sdk.GroupSyncRead(port, ph, 65, 1)
        read.addParam(1)
        read.addParam(2)
        assert read.txRxPacket() == OK and [read.getData(s, 65, 1) for s in (1, 2)] == [0, 1]
    finally:
        port.closePort()
        chain.close()
