"""The stock dynamixel_sdk (PortHandler + PacketHandler + groups) against the in-process chain."""

from __future__ import annotations

import dynamixel_sdk as sdk
from servoface.hardware.emulator import ServoChain

from tests.hardware.emulator.helpers import sdk_port

OK = 0


def chain_and_port(ids: list[int], **kw: object):  # type: ignore[no-untyped-def]
    chain = ServoChain.create(ids=ids, wire_time=False, **kw)  # type: ignore[arg-type]
    port, ph = sdk_port(chain)
    return chain, port, ph


def test_single_instructions() -> None:
    chain, port, ph = chain_and_port([1, 2])
    assert ph.ping(port, 1) == (1200, OK, 0)
    assert ph.write1ByteTxRx(port, 1, 64, 1) == (OK, 0)
    assert ph.write4ByteTxRx(port, 1, 116, 2100) == (OK, 0)
    assert ph.read4ByteTxRx(port, 1, 116) == (2100, OK, 0)
    assert ph.read2ByteTxRx(port, 1, 0) == (1200, OK, 0)
    assert ph.write1ByteTxRx(port, 1, 9, 0) == (OK, 7)  # EEPROM with torque on: access error
    assert ph.regWriteTxRx(port, 2, 65, 1, [1]) == (OK, 0)
    assert ph.action(port, 2) == OK
    assert chain.servo(2).read_register("LED") == 1
    assert ph.reboot(port, 1) == (OK, 0)
    assert ph.clearMultiTurn(port, 2) == (OK, 0)
    assert ph.factoryReset(port, 2, 0x02) == (OK, 0)
    assert chain.servo(2).read_register("LED") == 0


def test_groups_sync_bulk_and_fast() -> None:
    chain, port, ph = chain_and_port(list(range(1, 7)))
    for sid in range(1, 7):
        chain.servo(sid).move_by_hand(1000 + sid)
    write = sdk.GroupSyncWrite(port, ph, 65, 1)
    for sid in range(1, 7):
        write.addParam(sid, [1])
    assert write.txPacket() == OK
    assert all(chain.servo(s).read_register("LED") == 1 for s in range(1, 7))
    read = sdk.GroupSyncRead(port, ph, 132, 4)
    for sid in (6, 2, 4):
        read.addParam(sid)
    assert read.txRxPacket() == OK
    assert [read.getData(s, 132, 4) for s in (6, 2, 4)] == [1006, 1002, 1004]
    assert read.fastSyncRead() == OK
    assert [read.getData(s, 132, 4) for s in (6, 2, 4)] == [1006, 1002, 1004]
    bulk = sdk.GroupBulkRead(port, ph)
    bulk.addParam(1, 132, 4)
    bulk.addParam(3, 146, 1)
    assert bulk.txRxPacket() == OK
    assert (bulk.getData(1, 132, 4), bulk.getData(3, 146, 1)) == (1001, 25)
    assert bulk.fastBulkRead() == OK
    assert (bulk.getData(1, 132, 4), bulk.getData(3, 146, 1)) == (1001, 25)
    bw = sdk.GroupBulkWrite(port, ph)
    bw.addParam(1, 112, 4, [10, 0, 0, 0])
    bw.addParam(2, 65, 1, [0])
    assert bw.txPacket() == OK
    assert chain.servo(1).read_register("Profile Velocity") == 10 and chain.servo(2).read_register("LED") == 0


def test_broadcast_ping_finds_everyone() -> None:
    chain, port, ph = chain_and_port([3, 8, 11])
    found, comm = ph.broadcastPing(port)
    assert comm == OK
    assert found == {3: [1200, 52], 8: [1200, 52], 11: [1200, 52]}


def test_mixed_models_and_stuffed_values() -> None:
    chain = ServoChain.create(ids=[(1, "XL430-W250"), (2, "XM430-W350"), (3, "MX-28(2.0)")], wire_time=False)
    port, ph = sdk_port(chain)
    assert [ph.ping(port, i)[0] for i in (1, 2, 3)] == [1060, 1020, 30]
    # a value whose bytes contain FF FF FD exercises stuffing on both directions
    chain.servo(2).write_register("Operating Mode", 4)
    assert ph.write4ByteTxRx(port, 2, 20, 0x00FDFFFF) == (
        OK,
        4,
    )  # homing offset out of range (stuffed packet)
    chain.servo(2).move_by_hand(-515)  # 0xFFFFFDFD
    value, comm, err = ph.read4ByteTxRx(port, 2, 132)
    assert comm == OK and value == (-515) & 0xFFFFFFFF
