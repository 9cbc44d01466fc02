"""Every instruction, the answer rules and the error byte, exchanged as raw bytes (wire time off)."""

from __future__ import annotations

from servoface.hardware.emulator import Instruction as I
from servoface.hardware.emulator.crc import crc16
from servoface.hardware.emulator.packet import BROADCAST_ID

from tests.hardware.emulator.helpers import le, quick_chain, transact

OK, RESULT_FAIL, INSTRUCTION, CRC, RANGE, LENGTH, LIMIT, ACCESS = 0, 1, 2, 3, 4, 5, 6, 7


def rd(addr: int, n: int) -> bytes:
    return le(addr, 2) + le(n, 2)


def wr(addr: int, value: int, size: int) -> bytes:
    return le(addr, 2) + le(value, size)


def test_ping_unicast_broadcast_and_absent() -> None:
    chain, ser = quick_chain(ids=[3, 1, 7])
    (st,) = transact(ser, 1, I.PING)
    assert (st.id, st.error, st.data) == (1, 0, le(1200, 2) + bytes((52,)))
    assert transact(ser, 9, I.PING) == []
    replies = transact(ser, BROADCAST_ID, I.PING)
    assert [p.id for p in replies] == [1, 3, 7]


def test_read_and_write() -> None:
    chain, ser = quick_chain()
    (st,) = transact(ser, 2, I.READ, rd(132, 4))
    assert int.from_bytes(st.data, "little", signed=True) == 2048
    (st,) = transact(ser, 2, I.WRITE, wr(65, 1, 1))
    assert st.error == OK and st.data == b""
    assert chain.servo(2).read_register("LED") == 1
    (st,) = transact(ser, 2, I.READ, rd(7, 3))  # several registers at once
    assert st.data == bytes((2, 3, 250))


def test_reg_write_then_action() -> None:
    chain, ser = quick_chain()
    (st,) = transact(ser, 1, I.REG_WRITE, wr(65, 1, 1))
    assert st.error == OK
    assert chain.servo(1).read_register("LED") == 0
    assert chain.servo(1).read_register("Registered Instruction") == 1
    assert transact(ser, BROADCAST_ID, I.ACTION) == []
    assert chain.servo(1).read_register("LED") == 1
    assert chain.servo(1).read_register("Registered Instruction") == 0
    (st,) = transact(ser, 1, I.ACTION)  # nothing registered any more
    assert st.error == INSTRUCTION


def test_reboot_clears_torque_and_errors_then_brief_silence() -> None:
    chain, ser = quick_chain()
    servo = chain.servo(1)
    servo.write_register("Torque Enable", 1)
    chain.faults.inject(1, "encoder", duration_s=0.01)
    chain.advance(0.02)
    assert servo.read_register("Hardware Error Status") == 0x08
    (st,) = transact(ser, 1, I.REBOOT)
    assert st.error & 0x80  # alert still set in the reply
    assert transact(ser, 1, I.PING) == []  # rebooting
    chain.advance(chain.reboot_silence_s + 0.01)
    (st,) = transact(ser, 1, I.PING)
    assert st.error == 0
    assert servo.read_register("Torque Enable") == 0 and servo.read_register("Hardware Error Status") == 0


def test_factory_reset_options() -> None:
    chain, ser = quick_chain(ids=[5])
    servo = chain.servo(5)
    servo.write_register("Return Delay Time", 0)
    (st,) = transact(ser, 5, I.FACTORY_RESET, b"\x02")
    assert st.id == 5 and st.error == OK
    assert servo.read_register("Return Delay Time") == 250 and servo.id == 5 and servo.baud_bps == 1_000_000
    (st,) = transact(ser, 5, I.FACTORY_RESET, b"\x01")
    assert servo.id == 5 and servo.baud_bps == 57_600
    ser.baudrate = 57_600
    assert transact(ser, BROADCAST_ID, I.FACTORY_RESET, b"\xff") == []
    assert servo.id == 5  # broadcast 0xFF ignored
    (st,) = transact(ser, 5, I.FACTORY_RESET, b"\xff")
    assert st.id == 5
    assert servo.id == 1
    (st,) = transact(ser, 1, I.FACTORY_RESET, b"\x07")
    assert st.error == RANGE


def test_clear_multi_turn() -> None:
    chain, ser = quick_chain(ids=[1])
    servo = chain.servo(1)
    servo.write_register("Operating Mode", 4)
    servo.move_by_hand(3 * 4096 + 100)
    (st,) = transact(ser, 1, I.CLEAR, b"\x01\x44\x58\x4c")
    assert st.error == RANGE
    (st,) = transact(ser, 1, I.CLEAR, b"\x01\x44\x58\x4c\x22")
    assert st.error == OK
    assert servo.read_register("Present Position") == 100
    servo.write_register("Torque Enable", 1)
    servo.write_register("Goal Position", 3000)
    chain.advance(0.01)
    (st,) = transact(ser, 1, I.CLEAR, b"\x01\x44\x58\x4c\x22")
    assert st.error == RESULT_FAIL


def test_sync_read_answers_in_parameter_order_and_skips_absent() -> None:
    chain, ser = quick_chain(ids=[1, 2, 3])
    for sid in (1, 2, 3):
        chain.servo(sid).move_by_hand(1000 + sid)
    replies = transact(ser, BROADCAST_ID, I.SYNC_READ, rd(132, 4) + bytes((3, 9, 1, 2)))
    assert [(p.id, int.from_bytes(p.data, "little")) for p in replies] == [(3, 1003), (1, 1001), (2, 1002)]


def test_sync_write_and_bulk_write() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    params = rd(116, 4)[:2] + le(4, 2) + bytes((1,)) + le(150, 4) + bytes((2,)) + le(170, 4)
    assert transact(ser, BROADCAST_ID, I.SYNC_WRITE, params) == []
    assert [chain.servo(i).read_register("Goal Position") for i in (1, 2)] == [150, 170]
    bulk = bytes((1,)) + le(65, 2) + le(1, 2) + b"\x01" + bytes((2,)) + le(112, 2) + le(4, 2) + le(77, 4)
    assert transact(ser, BROADCAST_ID, I.BULK_WRITE, bulk) == []
    assert chain.servo(1).read_register("LED") == 1 and chain.servo(2).read_register("Profile Velocity") == 77
    assert [g[1:] for g in chain.goal_writes()] == [(1, 150), (2, 170)]


def test_bulk_read_in_order() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    params = bytes((2,)) + rd(146, 1) + bytes((1,)) + rd(7, 2)
    replies = transact(ser, BROADCAST_ID, I.BULK_READ, params)
    assert [(p.id, p.data) for p in replies] == [(2, bytes((25,))), (1, bytes((1, 3)))]


def _fast_blocks(raw: bytes, length: int) -> list[tuple[int, int, bytes, bytes]]:
    body = raw[8:]
    out = []
    for i in range(0, len(body), length + 4):
        blk = body[i : i + length + 4]
        out.append((blk[0], blk[1], blk[2 : 2 + length], blk[2 + length :]))
    return out


def test_fast_sync_read_layout() -> None:
    chain, ser = quick_chain(ids=[1, 2, 3])
    ser.write(
        bytes(
            __import__("servoface.hardware.emulator", fromlist=["x"]).build_instruction(
                BROADCAST_ID, I.FAST_SYNC_READ, rd(132, 4) + bytes((2, 1, 3))
            )
        )
    )
    raw = ser.read(1000)
    assert raw[:8] == b"\xff\xff\xfd\x00\xfe" + le(1 + 3 * (4 + 4), 2) + b"\x55"
    assert len(raw) == 8 + 3 * (4 + 4)  # reference sheet §8: 8 + N(L + 4)
    blocks = _fast_blocks(raw, 4)
    assert [(b[0], b[1], int.from_bytes(b[2], "little")) for b in blocks] == [
        (0, 2, 2048),
        (0, 1, 2048),
        (0, 3, 2048),
    ]
    assert int.from_bytes(raw[-2:], "little") == crc16(raw[:-2])  # last block's CRC is the packet CRC
    first_end = 8 + 6
    assert int.from_bytes(raw[first_end : first_end + 2], "little") == crc16(raw[:first_end])  # running CRC


def test_fast_bulk_read_layout() -> None:
    from servoface.hardware.emulator import build_instruction

    chain, ser = quick_chain(ids=[1, 2])
    ser.write(build_instruction(BROADCAST_ID, I.FAST_BULK_READ, bytes((1,)) + rd(146, 1) + bytes((2,)) + rd(132, 4)))
    raw = ser.read(1000)
    assert raw[5] | raw[6] << 8 == 1 + (1 + 4) + (4 + 4)
    assert raw[8:11] == bytes((0, 1, 25)) and raw[13:15] == bytes((0, 2))
    assert int.from_bytes(raw[-2:], "little") == crc16(raw[:-2])


def test_error_byte_cases() -> None:
    chain, ser = quick_chain(ids=[1])
    servo = chain.servo(1)
    bad = bytearray(__import__("servoface.hardware.emulator", fromlist=["x"]).build_instruction(1, I.READ, rd(132, 4)))
    bad[-1] ^= 0x55
    ser.write(bytes(bad))
    from servoface.hardware.emulator.packet import PacketReceiver

    (st,) = PacketReceiver().feed(ser.read(100))
    assert st.error == CRC
    assert transact(ser, 1, 0x7E)[0].error == INSTRUCTION
    assert transact(ser, 1, I.WRITE, wr(64, 2, 1))[0].error == RANGE  # torque enable is 0/1
    assert transact(ser, 1, I.WRITE, wr(11, 2, 1))[0].error == RANGE  # no operating mode 2
    assert transact(ser, 1, I.WRITE, wr(116, 100, 2))[0].error == LENGTH  # half a Goal Position
    assert transact(ser, 1, I.WRITE, wr(132, 5, 4))[0].error == ACCESS  # read-only
    assert transact(ser, 1, I.WRITE, wr(14, 5, 1))[0].error == ACCESS  # undefined address
    servo.write_register("Max Position Limit", 3000)
    assert transact(ser, 1, I.WRITE, wr(116, 3500, 4))[0].error == LIMIT
    assert servo.read_register("Goal Position") != 3500  # nothing changed
    assert transact(ser, 1, I.WRITE, wr(64, 1, 1))[0].error == OK
    assert transact(ser, 1, I.WRITE, wr(9, 0, 1))[0].error == ACCESS  # EEPROM while torque on
    assert servo.read_register("Return Delay Time") == 250
    assert transact(ser, 1, I.READ, rd(4000, 4))[0].error == ACCESS


def test_alert_bit_while_hardware_error() -> None:
    chain, ser = quick_chain(ids=[1])
    assert transact(ser, 1, I.PING)[0].error == 0
    chain.faults.inject(1, "electrical_shock", duration_s=0.001)
    chain.advance(0.01)
    (st,) = transact(ser, 1, I.READ, rd(70, 1))
    assert st.error == 0x80 and st.data == bytes((0x10,))


def test_status_return_level() -> None:
    chain, ser = quick_chain(ids=[1])
    assert transact(ser, 1, I.WRITE, wr(68, 1, 1))[0].error == OK  # the reply comes at the old level
    assert transact(ser, 1, I.WRITE, wr(65, 1, 1)) == []
    assert chain.servo(1).read_register("LED") == 1  # applied, just not answered
    assert len(transact(ser, 1, I.READ, rd(65, 1))) == 1
    transact(ser, 1, I.WRITE, wr(68, 0, 1))
    assert transact(ser, 1, I.READ, rd(65, 1)) == []
    assert len(transact(ser, 1, I.PING)) == 1  # ping always answered
    assert transact(ser, BROADCAST_ID, I.SYNC_READ, rd(65, 1) + b"\x01") == []


def test_broadcast_write_applies_silently_and_broadcast_read_is_ignored() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    assert transact(ser, BROADCAST_ID, I.WRITE, wr(65, 1, 1)) == []
    assert [chain.servo(i).read_register("LED") for i in (1, 2)] == [1, 1]
    assert transact(ser, BROADCAST_ID, I.READ, rd(65, 1)) == []


def test_id_change_answers_with_old_id_then_new() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    (st,) = transact(ser, 1, I.WRITE, wr(7, 9, 1))
    assert st.id == 1
    assert transact(ser, 1, I.PING) == []
    assert transact(ser, 9, I.PING)[0].id == 9
    assert chain.servo(1).id == 9  # looked up by creation id


def test_baud_mismatch_means_silence_and_baud_change_takes_effect() -> None:
    chain, ser = quick_chain(ids=[1])
    ser.baudrate = 57_600
    assert transact(ser, 1, I.PING) == []
    ser.baudrate = 1_000_000
    (st,) = transact(ser, 1, I.WRITE, wr(8, 6, 1))
    assert st.error == OK
    assert transact(ser, 1, I.PING) == []
    ser.baudrate = 4_000_000
    assert len(transact(ser, 1, I.PING)) == 1


def test_log_records_decoded_packets() -> None:
    chain, ser = quick_chain(ids=[1])
    transact(ser, 1, I.WRITE, wr(116, 1234, 4))
    entry = chain.log[-1]
    assert (entry.id, entry.instruction, entry.params) == (1, I.WRITE, wr(116, 1234, 4))
    assert chain.goal_writes() == [(entry.t_s, 1, 1234)]
    assert chain.instructions(I.WRITE) == [entry]


def test_indirect_addressing_reads_and_writes_through() -> None:
    chain, ser = quick_chain(ids=[1], model="XL430-W250")
    servo = chain.servo(1)
    # map Indirect Data 1..4 -> Present Position, 5..8 -> Goal Position
    for i in range(4):
        assert transact(ser, 1, I.WRITE, wr(168 + 2 * i, 132 + i, 2))[0].error == OK
        assert transact(ser, 1, I.WRITE, wr(176 + 2 * i, 116 + i, 2))[0].error == OK
    servo.move_by_hand(1234)
    (st,) = transact(ser, 1, I.READ, rd(224, 4))
    assert int.from_bytes(st.data, "little") == 1234
    assert transact(ser, 1, I.WRITE, wr(228, 2222, 4))[0].error == OK
    assert servo.read_register("Goal Position") == 2222
    assert transact(ser, 1, I.WRITE, le(228, 2) + le(7, 2))[0].error == LENGTH  # half a Goal Position
    assert transact(ser, 1, I.WRITE, wr(224, 5, 4))[0].error == ACCESS  # Present Position is read-only


def test_id_and_baud_changed_through_test_hooks_are_heard() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    assert len(transact(ser, 2, I.PING)) == 1
    chain.servo(2).write_register("ID", 12)
    assert transact(ser, 2, I.PING) == [] and transact(ser, 12, I.PING)[0].id == 12
    chain.servo(1).write_register("Baud Rate", 1)
    assert transact(ser, 1, I.PING) == []


def test_control_table_backup_answers() -> None:
    chain, ser = quick_chain(ids=[1])
    (st,) = transact(ser, 1, I.CONTROL_TABLE_BACKUP, b"\x01\x43\x54\x52\x4c")
    assert (st.id, st.error) == (1, OK)


def test_indirect_address_beyond_the_table_is_refused() -> None:
    """e-manual XL330-M288, Indirect Address: range 64~227 (the table ends at 227)."""
    chain, ser = quick_chain(ids=[1])
    assert transact(ser, 1, I.WRITE, wr(168, 600, 2))[0].error == RANGE
    (st,) = transact(ser, 1, I.READ, rd(208, 1))
    assert (st.error, st.data) == (OK, b"\x00")


def test_broadcast_reboot_and_reset_are_silent_but_act() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    for sid in (1, 2):
        chain.servo(sid).write_register("LED", 1)
    assert transact(ser, BROADCAST_ID, I.REBOOT) == []
    chain.advance(chain.reboot_silence_s + 0.01)
    assert [chain.servo(s).read_register("LED") for s in (1, 2)] == [0, 0]
    chain.servo(2).write_register("Return Delay Time", 7)
    assert transact(ser, BROADCAST_ID, I.FACTORY_RESET, b"\x02") == []
    assert chain.servo(2).read_register("Return Delay Time") == 250
    assert [chain.servo(s).id for s in (1, 2)] == [1, 2]


def test_bulk_read_skips_absent_ids_and_keeps_order() -> None:
    chain, ser = quick_chain(ids=[1, 2])
    params = bytes((2,)) + rd(7, 1) + bytes((5,)) + rd(7, 1) + bytes((1,)) + rd(7, 1)
    assert [(p.id, p.data) for p in transact(ser, BROADCAST_ID, I.BULK_READ, params)] == [
        (2, b"\x02"),
        (1, b"\x01"),
    ]


def test_unicast_sync_instructions_are_ignored() -> None:
    chain, ser = quick_chain(ids=[1])
    assert transact(ser, 1, I.SYNC_READ, rd(132, 4) + b"\x01") == []
    assert transact(ser, 1, I.SYNC_WRITE, le(65, 2) + le(1, 2) + b"\x01\x01") == []
    assert chain.servo(1).read_register("LED") == 0


def test_goal_limit_policy_clamp() -> None:
    chain, ser = quick_chain(ids=[1], goal_limit="clamp")
    servo = chain.servo(1)
    servo.write_register("Max Position Limit", 3000)
    servo.write_register("Torque Enable", 1)
    assert transact(ser, 1, I.WRITE, wr(116, 3500, 4))[0].error == OK
    chain.advance(2.0)
    assert servo.read_register("Present Position") == 3000
    assert chain.goal_writes()[-1][1:] == (1, 3500)  # the log shows what the host sent
