"""CRC-16 against the e-manual vectors, packet build/parse, byte stuffing both ways."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from servoface.hardware.emulator import PacketError, build_instruction, build_status, parse_packet
from servoface.hardware.emulator.crc import crc16, crc16_bitwise, crc16_even, crc16_own_tail
from servoface.hardware.emulator.fast_read import needs_stuffing
from servoface.hardware.emulator.packet import PacketReceiver, stuff, unstuff

# (bytes after FF FF FD 00, expected CRC_L CRC_H) - the 15 examples of the e-manual (reference sheet §1)
VECTORS = [
    ("01 03 00 01", "19 4E"),
    ("01 07 00 55 00 06 04 26", "65 5D"),
    ("FE 03 00 01", "31 42"),
    ("01 07 00 02 84 00 04 00", "1D 15"),
    ("01 08 00 55 00 A6 00 00 00", "8C C0"),
    ("01 09 00 03 74 00 00 02 00 00", "CA 89"),
    ("01 04 00 55 00", "A1 0C"),
    ("01 03 00 08", "2F 4E"),
    ("01 03 00 05", "02 CE"),
    ("01 04 00 06 01", "A1 E6"),
    ("01 08 00 10 01 44 58 4C 22", "B1 DC"),
    ("FE 09 00 82 84 00 04 00 01 02", "CE FA"),
    ("FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00", "82 87"),
    ("FE 0D 00 92 01 90 00 02 00 02 92 00 01 00", "1A 05"),
    ("FE 10 00 93 01 20 00 02 00 A0 00 02 1F 00 01 00 50", "B7 68"),
]


@pytest.mark.parametrize(("body", "crc"), VECTORS)
def test_crc_matches_emanual_vector(body: str, crc: str) -> None:
    data = bytes.fromhex("FF FF FD 00 " + body)
    expected = bytes.fromhex(crc)
    value = crc16(data)
    assert bytes((value & 0xFF, value >> 8)) == expected
    assert crc16_bitwise(data) == value


@pytest.mark.parametrize(("body", "crc"), VECTORS)
def test_builder_reproduces_emanual_packet(body: str, crc: str) -> None:
    raw = bytes.fromhex("FF FF FD 00 " + body + " " + crc)
    pid, inst, params = raw[4], raw[7], raw[8:-2]
    built = build_status(pid, params[0], params[1:]) if inst == 0x55 else build_instruction(pid, inst, params)
    assert built == raw
    packet = parse_packet(raw)
    assert (packet.id, packet.instruction, packet.params) == (pid, inst, params)


@given(st.binary(max_size=300), st.integers(0, 0xFFFF))
def test_table_crc_equals_bitwise_crc(data: bytes, start: int) -> None:
    assert crc16(data, start) == crc16_bitwise(data, start)


@given(st.binary(max_size=40), st.integers(0, 0xFFFF))
def test_fast_read_block_crc_equals_bitwise_crc(data: bytes, start: int) -> None:
    """The Fast Sync Read reply's per-block steps (`crc16_even`, `crc16_own_tail`) equal the textbook CRC."""
    even = data[: len(data) & ~1]
    assert crc16_even(even, start) == crc16_bitwise(even, start)
    assert crc16_own_tail(start) == crc16_bitwise(bytes((start & 0xFF, start >> 8)), start)


@given(st.lists(st.sampled_from([b"\xff", b"\xfd", b"\x55", b"\x00", b"\xff\xff\xfd"]), max_size=12))
def test_fast_read_stuffing_check_equals_the_copying_check(pieces: list[bytes]) -> None:
    logical = b"".join(pieces)
    assert needs_stuffing(logical) == (b"\xff\xff\xfd" in bytes((0x55,)) + logical[:-2])


def test_stuffing_inserts_fd_after_header_pattern() -> None:
    assert stuff(b"\x03\xff\xff\xfd\x01") == b"\x03\xff\xff\xfd\xfd\x01"
    packet = build_instruction(1, 0x03, b"\x74\x00\xff\xff\xfd\x00")
    assert packet[5] | packet[6] << 8 == 3 + 6 + 1  # LEN grew by the stuffed byte
    assert parse_packet(packet).params == b"\x74\x00\xff\xff\xfd\x00"


@given(st.lists(st.sampled_from([b"\xff", b"\xfd", b"\x00", b"\xff\xff\xfd", b"\xfd\xfd", b"\x55"]), max_size=40))
def test_stuff_unstuff_round_trip(parts: list[bytes]) -> None:
    body = b"".join(parts)
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    # after stuffing, every FF FF FD is followed by FD: no false header inside the body
    i = stuffed.find(b"\xff\xff\xfd")
    while i >= 0:
        assert stuffed[i + 3 : i + 4] == b"\xfd"
        i = stuffed.find(b"\xff\xff\xfd", i + 1)


@given(
    st.integers(0, 252),
    st.sampled_from([0x01, 0x02, 0x03, 0x83, 0x92]),
    st.lists(st.sampled_from([b"\xff", b"\xfd", b"\x00", b"\xff\xff\xfd", b"\x7f"]), max_size=30),
)
def test_build_parse_round_trip_and_sdk_agrees(pid: int, inst: int, parts: list[bytes]) -> None:
    from dynamixel_sdk import PacketHandler

    params = b"".join(parts)
    packet = build_instruction(pid, inst, params)
    parsed = parse_packet(packet)
    assert (parsed.id, parsed.instruction, parsed.params) == (pid, inst, params)
    # the stock SDK stuffs and CRCs the same instruction identically
    sdk = PacketHandler(2.0)
    tx = [0xFF, 0xFF, 0xFD, 0x00, pid, (len(params) + 3) & 0xFF, (len(params) + 3) >> 8, inst, *params, 0, 0]
    tx = sdk.addStuffing(tx)
    total = (tx[5] | tx[6] << 8) + 7
    crc = sdk.updateCRC(0, tx, total - 2)
    assert bytes(tx[: total - 2]) + bytes((crc & 0xFF, crc >> 8)) == packet


@given(st.binary(max_size=20), st.lists(st.integers(1, 30), max_size=10))
def test_receiver_finds_packets_across_arbitrary_splits(garbage: bytes, cuts: list[int]) -> None:
    garbage = garbage.replace(b"\xff", b"\x00")
    stream = (
        garbage + build_instruction(1, 0x02, b"\x84\x00\x04\x00") + build_instruction(0xFE, 0x83, b"\xff\xff\xfd" * 3)
    )
    receiver = PacketReceiver()
    found = []
    pos = 0
    for cut in cuts:
        found += receiver.feed(stream[pos : pos + cut])
        pos += cut
    found += receiver.feed(stream[pos:])
    assert [(p.id, p.instruction) for p in found] == [(1, 0x02), (0xFE, 0x83)]
    assert found[1].params == b"\xff\xff\xfd" * 3
    assert all(p.crc_ok for p in found)


def test_receiver_flags_bad_crc_and_parse_rejects_it() -> None:
    packet = bytearray(build_instruction(1, 0x01))
    packet[-1] ^= 0xFF
    (found,) = PacketReceiver().feed(bytes(packet))
    assert not found.crc_ok
    with pytest.raises(PacketError, match="CRC"):
        parse_packet(bytes(packet))


def test_parse_rejects_bad_header_and_length() -> None:
    with pytest.raises(PacketError, match="header"):
        parse_packet(b"\xff\xff\xfe\x00\x01\x03\x00\x01\x00\x00")
    with pytest.raises(PacketError, match="length"):
        parse_packet(build_instruction(1, 0x01) + b"\x00")
    with pytest.raises(PacketError, match="packet id"):
        build_instruction(0xFD, 0x01)
