"""Whatever arrives on the wire, the emulated chain neither crashes nor answers with malformed packets."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.hardware.emulator import ServoChain, build_instruction
from servoface.hardware.emulator.packet import PacketReceiver

INSTRUCTIONS = [
    0x01,
    0x02,
    0x03,
    0x04,
    0x05,
    0x06,
    0x08,
    0x10,
    0x20,
    0x82,
    0x83,
    0x8A,
    0x92,
    0x93,
    0x9A,
    0x7F,
]


def _chain() -> tuple[ServoChain, object]:
    chain = ServoChain.create(ids=[1, 2, 3], wire_time=False, clock="manual")
    return chain, chain.open_serial()


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from([1, 2, 3, 9, 0xFE]),
            st.sampled_from(INSTRUCTIONS),
            st.binary(max_size=24),
        ),
        max_size=6,
    )
)
def test_random_instructions_never_crash_and_replies_are_well_formed(
    packets: list[tuple[int, int, bytes]],
) -> None:
    chain, ser = _chain()
    for pid, inst, params in packets:
        ser.write(build_instruction(pid, inst, params))  # type: ignore[attr-defined]
        chain.advance(0.2)  # past any reboot silence
        raw = ser.read(1 << 16)  # type: ignore[attr-defined]
        if inst in (0x8A, 0x9A):
            continue  # a fast-read reply may be deliberately short when a listed id is absent
        for status in PacketReceiver().feed(raw):
            assert status.crc_ok and status.instruction == 0x55
            assert status.id in (1, 2, 3) or pid != 0xFE
    assert len(chain.log) == len(packets)


NOISE = st.lists(
    st.one_of(
        st.binary(max_size=12),
        st.sampled_from([b"\xff", b"\xff\xff\xfd", b"\xff\xff\xfd\x00", b"\xff\xff\xfd\x00\x02\xff\x01"]),
    ),
    max_size=12,
).map(b"".join)


@settings(max_examples=150, deadline=None)
@given(NOISE)
def test_line_noise_is_ignored(noise: bytes) -> None:
    chain, ser = _chain()
    ser.write(noise)  # type: ignore[attr-defined]
    ser.reset_input_buffer()  # type: ignore[attr-defined]  # whatever the noise provoked
    # the next whole packet is understood: the receiver resynchronises on it
    ser.write(build_instruction(2, 0x01))  # type: ignore[attr-defined]
    found = [p for p in PacketReceiver().feed(ser.read(1 << 16)) if p.id == 2]  # type: ignore[attr-defined]
    assert [(p.error, p.data) for p in found] == [(0, bytes((0xB0, 0x04, 52)))]


def test_partial_packet_is_abandoned_after_the_line_goes_idle() -> None:
    chain, ser = _chain()
    ser.write(b"\xff\xff\xfd\x00\x01\xff\x00\x02")  # type: ignore[attr-defined]  # claims 255 more bytes
    chain.advance(0.05)
    ser.write(build_instruction(1, 0x01)[:6])  # type: ignore[attr-defined]  # a ping in two pieces
    ser.write(build_instruction(1, 0x01)[6:])  # type: ignore[attr-defined]
    (status,) = PacketReceiver().feed(ser.read(100))  # type: ignore[attr-defined]
    assert status.id == 1 and status.error == 0
