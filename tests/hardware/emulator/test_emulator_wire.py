"""Wire time (manual clock): instruction bytes, Return Delay Time, byte-by-byte arrival, queueing."""

from __future__ import annotations

import pytest
from servoface.hardware.emulator import ServoChain, build_instruction
from servoface.hardware.emulator.packet import BROADCAST_ID

from tests.hardware.emulator.helpers import le

BYTE_1M = 10e-6


def wired(ids: list[int], rdt: int = 250, baud: int = 1_000_000) -> tuple[ServoChain, object]:
    chain = ServoChain.create(ids=ids, baud=baud, wire_time=True, clock="manual")
    for sid in ids:
        chain.servo(sid).write_register("Return Delay Time", rdt)
    return chain, chain.open_serial()


def test_ping_reply_arrives_after_instruction_rdt_and_its_own_bytes() -> None:
    chain, ser = wired([1])
    ser.write(build_instruction(1, 0x01))  # 10 bytes
    t_rx = 10 * BYTE_1M
    first_byte = t_rx + 500e-6 + BYTE_1M
    chain.advance(first_byte - 1e-7)
    assert ser.in_waiting == 0 and ser.read(100) == b""
    chain.advance(2e-7)
    assert ser.in_waiting == 1
    chain.advance(5 * BYTE_1M)
    assert len(ser.read(100)) == 6  # byte by byte as they arrive
    chain.advance(8 * BYTE_1M)
    rest = ser.read(100)
    assert len(rest) == 8  # 14-byte status in total
    assert ser.read(100) == b""


def test_sync_read_replies_queue_in_order_each_after_its_rdt() -> None:
    chain, ser = wired([1, 2, 3], rdt=50)  # 100 us each
    packet = build_instruction(BROADCAST_ID, 0x82, le(132, 2) + le(4, 2) + bytes((1, 2, 3)))
    ser.write(packet)
    t_rx = len(packet) * BYTE_1M
    status = 15 * BYTE_1M
    third_starts = t_rx + 2 * (100e-6 + status) + 100e-6
    chain.advance(third_starts - 1e-7)  # two replies complete, the third still waiting out its RDT
    assert len(ser.read(1000)) == 30
    chain.advance(status + 2e-7)
    assert len(ser.read(1000)) == 15


def test_lower_baud_is_slower() -> None:
    chain, ser = wired([1], rdt=0, baud=57_600)
    ser.baudrate = 57_600
    ser.write(build_instruction(1, 0x01))
    chain.advance(24 * 10 / 57_600 - 1e-6)
    assert ser.in_waiting == 13
    chain.advance(2e-6)
    assert ser.in_waiting == 14


def test_back_to_back_writes_queue_on_the_line() -> None:
    chain, ser = wired([1, 2], rdt=0)
    ser.write(build_instruction(1, 0x01))
    ser.write(build_instruction(2, 0x01))  # sent while the first is still on the wire
    chain.advance((10 + 10 + 14 + 14) * BYTE_1M + 1e-7)
    assert ser.in_waiting == 28


def test_wire_time_off_is_immediate() -> None:
    chain = ServoChain.create(ids=[1], wire_time=False, clock="manual")
    ser = chain.open_serial()
    ser.write(build_instruction(1, 0x01))
    assert len(ser.read(100)) == 14


def test_reset_input_buffer_drops_only_arrived_bytes() -> None:
    chain, ser = wired([1], rdt=0)
    ser.write(build_instruction(1, 0x01))
    chain.advance((10 + 4) * BYTE_1M + 1e-7)
    ser.reset_input_buffer()
    assert ser.in_waiting == 0
    chain.advance(10 * BYTE_1M)
    assert len(ser.read(100)) == 10  # the rest of the packet was still on the wire


def test_sdk_against_real_clock_with_wire_time() -> None:
    """The stock SDK's timeouts work against wire-timed replies (RDT default 500 us)."""
    from tests.hardware.emulator.helpers import sdk_port

    chain = ServoChain.create(ids=[1, 2], wire_time=True)
    port, ph = sdk_port(chain)
    model, comm, err = ph.ping(port, 2)
    assert (model, comm, err) == (1200, 0, 0)
    value, comm, err = ph.read4ByteTxRx(port, 1, 132)
    assert (value, comm) == (2048, 0)


def test_closed_endpoint_raises() -> None:
    from servoface.hardware.emulator import PortClosedError

    chain = ServoChain.create(ids=[1], wire_time=False)
    ser = chain.open_serial()
    ser.close()
    with pytest.raises(PortClosedError):
        ser.write(b"\x00")


def test_packet_delivery_hands_over_whole_status_packets() -> None:
    chain = ServoChain.create(ids=[1], wire_time=True, clock="manual", delivery="packet")
    chain.servo(1).write_register("Return Delay Time", 0)
    ser = chain.open_serial()
    ser.write(build_instruction(1, 0x01))
    chain.advance((10 + 13) * BYTE_1M)
    assert ser.in_waiting == 0  # 13 of 14 bytes on the wire: nothing handed over yet
    chain.advance(BYTE_1M + 1e-7)
    assert len(ser.read(100)) == 14


def test_closed_chain_closes_its_endpoints() -> None:
    from servoface.hardware.emulator import PortClosedError

    chain = ServoChain.create(ids=[1], wire_time=False)
    ser = chain.open_serial()
    chain.close()
    with pytest.raises(PortClosedError, match="chain was closed"):
        ser.read(1)
