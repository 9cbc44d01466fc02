"""Transmit back-pressure: a host cannot write faster than the wire carries (in-process port and pty).

A real serial port queues at most its transmit buffer ahead of the line; ``write()`` then blocks at the
wire rate and ``flush()`` (tcdrain) waits until the last byte is out. The wire rate is the e-manual's
"DYNAMIXEL Protocol 2.0" framing at the Baud Rate(8): 10 bits per byte (8N1, 1 start and 1 stop bit).
"""

from __future__ import annotations

import time

from servoface.hardware.emulator import ServoChain, build_instruction
from servoface.hardware.emulator.packet import BROADCAST_ID, Instruction

BAUD = 57_600
BYTES_PER_S = BAUD / 10.0
TX_BUFFER_BYTES = 1024  # the default transmit buffer (an FT232H-class adapter: 1 KB)


def _sync_write(ids: range) -> bytes:
    params = (116).to_bytes(2, "little") + (4).to_bytes(2, "little")
    for sid in ids:
        params += bytes((sid,)) + (2048).to_bytes(4, "little")
    return build_instruction(BROADCAST_ID, Instruction.SYNC_WRITE, params)


def test_in_process_write_blocks_at_the_wire_rate() -> None:
    """e-manual Baud Rate(8) / Protocol 2.0 framing: 57 600 bps carries 5 760 bytes/s, so that is all a
    writer gets through per second, plus one transmit buffer."""
    chain = ServoChain.create(ids=range(1, 7), baud=BAUD)
    ser = chain.open_serial()
    packet = _sync_write(range(1, 7))
    sent = 0
    t0 = time.monotonic()
    while time.monotonic() - t0 < 0.4:
        sent += ser.write(packet)
    elapsed = time.monotonic() - t0
    assert sent <= (elapsed + 0.01) * BYTES_PER_S + TX_BUFFER_BYTES + len(packet)
    assert chain.tx_backlog_s() <= (TX_BUFFER_BYTES + len(packet)) / BYTES_PER_S
    ser.flush()
    assert chain.tx_backlog_s() == 0.0  # flush(): every byte is on the wire
    chain.close()


def test_manual_clock_moves_on_while_write_blocks() -> None:
    """With a manual clock the blocked write is time passing: 200 Sync Writes take their wire time."""
    chain = ServoChain.create(ids=range(1, 25), baud=1_000_000, clock="manual")
    ser = chain.open_serial()
    packet = _sync_write(range(1, 25))
    for _ in range(200):
        ser.write(packet)
    wire_s = 200 * len(packet) * 10 / 1_000_000
    assert chain.time_s >= wire_s - TX_BUFFER_BYTES * 10 / 1_000_000 - 1e-9
    ser.flush()
    assert chain.time_s >= wire_s - 1e-9


def test_pty_client_blocks_at_the_wire_rate() -> None:
    """Over the pty the client's write() blocks once the chain's transmit buffer and the kernel's pty buffer
    (about 18 KB here; allowed 64 KB) are full; the virtual line never runs more than a buffer behind.
    The allowance is generous because the kernel buffer drains at the wire rate too (seconds at 57 600)."""
    import serial

    chain = ServoChain.create(ids=range(1, 7), baud=BAUD)
    path = chain.serve_pty()
    port = serial.Serial(path, BAUD, timeout=0)
    packet = _sync_write(range(1, 7))
    sent = 0
    t0 = time.monotonic()
    while time.monotonic() - t0 < 1.0:
        sent += port.write(packet)
    elapsed = time.monotonic() - t0
    kernel_allowance = 64 * 1024
    assert sent <= (elapsed + 0.05) * BYTES_PER_S + TX_BUFFER_BYTES + kernel_allowance
    assert chain.tx_backlog_s() <= (TX_BUFFER_BYTES + 2 * len(packet)) / BYTES_PER_S + 0.05
    port.close()
    chain.close()
