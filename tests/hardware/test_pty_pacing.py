"""The emulator served on a pty paces the wire at the baud the host set: a reply cannot come sooner than its
bytes take at 10 bit / baud (so `servoface bench bus`'s "share of the wire" over a pty is honest)."""

from __future__ import annotations

import sys
import time

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.dynamixel_bus import sdk
from servoface.hardware.emulator import ServoChain
from servoface.hardware.registers import Register, span
from servoface.hardware.wire import status_bytes, sync_read_instruction_bytes

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")

N = 24
BLOCK = (Register.MODEL_NUMBER, Register.PRESENT_TEMPERATURE)  # 0..146: 147 data bytes per reply


@pytest.mark.parametrize("baud", [1_000_000, 4_000_000])
def test_pty_replies_take_at_least_their_wire_time(baud: int) -> None:
    chain = ServoChain.create(ids=range(1, N + 1), model="XL330-M288", baud=baud, wire_time=True)
    try:
        path = chain.serve_pty()
        bus = open_bus("dynamixel", port=path, baud=baud, warn_latency=False)
        try:
            ids = list(range(1, N + 1))
            for sid in ids:
                bus.write(sid, Register.RETURN_DELAY_TIME, 0)
            assert chain._pty.host_baud() == baud  # what the pty thread paces at
            length = span(BLOCK)[1]
            wire_s = (sync_read_instruction_bytes(N) + N * status_bytes(length)) * 10.0 / baud
            got = bus.sync_read(ids, BLOCK)  # the SDK parses them: every servo answers the whole block
            assert sorted(got) == ids and {v[Register.MODEL_NUMBER] for v in got.values()} == {1200}
            port, packet = bus.sdk_handlers()  # the same instruction through the SDK, the replies' bytes
            # timed as they arrive: the stock `PortHandler.readPort` (servoface's sleeps out the wire time it
            # computes itself, which would hide an emulator that is too fast), no parse in the way
            stock_read = sdk.PortHandler.readPort
            expected = N * status_bytes(length)
            for _ in range(3):
                port.is_using = False  # the SDK's own flag: its txPacket leaves it set until a reply is read
                t0 = time.perf_counter()
                assert packet.syncReadTx(port, 0, length, ids, N, False) == 0  # COMM_SUCCESS
                received = 0
                while received < expected and time.perf_counter() - t0 < 2.0:
                    received += len(stock_read(port, expected - received))
                elapsed_s = time.perf_counter() - t0
                assert received == expected
                assert elapsed_s >= wire_s, f"replies in {elapsed_s * 1e3:.2f} ms < wire {wire_s * 1e3:.2f} ms"
        finally:
            bus.close()
    finally:
        chain.close()
