"""A pair of real ptys whose slaves a `_WindowedPort` opens as the SDK does (``serial.Serial(..., timeout=0)``):
one reading and writing its fd raw (servoface's path), one through pyserial's own ``read`` and ``write`` (the
reference). For tests/hardware/test_bus_raw_write.py and test_bus_fast_read.py."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from typing import Any

from servoface.hardware.dynamixel_bus import _WindowedPort


class PtyPort:
    """One pty: ``master`` is the far end; ``port`` the `_WindowedPort` on the slave."""

    def __init__(self, raw: bool) -> None:
        self.master, slave = os.openpty()
        self.port = _WindowedPort(os.ttyname(slave))
        self.port.baudrate = 1_000_000
        assert self.port.openPort()
        os.close(slave)
        self.written = self.drained = 0  # bytes `write` reported written / `drain` read at the far end
        if not raw:
            self.port._raw_read = self.port._raw_write = False  # pyserial's own read and write, the reference

    def write(self, packet: Any) -> tuple[str, Any]:
        """``writePort(packet)``'s result, or its error's type name and message."""
        try:
            n = self.port.writePort(packet)
        except Exception as err:
            return type(err).__name__, str(err)
        self.written += int(n)
        return "ok", n

    def read(self, size: int) -> tuple[str, Any]:
        """``readPort(size)``'s result, or its error's type name and message."""
        try:
            return "ok", self.port.readPort(size)
        except Exception as err:
            return type(err).__name__, str(err)

    def feed(self, data: bytes) -> None:
        """Write ``data`` at the far end and wait until all of it can be read (a pty hands it over later)."""
        before = self.port.ser.in_waiting
        os.write(self.master, data)
        deadline = time.monotonic() + 2.0
        while self.port.ser.in_waiting < before + len(data) and time.monotonic() < deadline:
            time.sleep(0.0005)

    def drain(self, expect: int | None = None) -> bytes:
        """Everything written so far, as the far end reads it: at least ``expect`` bytes (default: what
        `write` reported and no drain has read yet) as they come, up to 10 s (a loaded machine may hand
        them over late; stopping early would leave a writer blocked on a full pty), then whatever else
        comes within 50 ms (bytes nobody reported)."""
        want = self.written - self.drained if expect is None else expect
        out = b""
        os.set_blocking(self.master, False)
        give_up = time.monotonic() + 10.0
        deadline = time.monotonic() + 0.05
        while time.monotonic() < deadline or (len(out) < want and time.monotonic() < give_up):
            try:
                got = os.read(self.master, 65536)
            except BlockingIOError:
                time.sleep(0.002)
                continue
            except OSError:
                break
            if got:
                out += got
                deadline = time.monotonic() + 0.05
        self.drained += len(out)
        return out

    def close(self) -> None:
        try:
            os.close(self.master)
        except OSError:
            pass
        if self.port.is_open:
            self.port.closePort()


def pty_pair() -> Iterator[tuple[PtyPort, PtyPort]]:
    """(pyserial's reference, raw) for a fixture to yield from; both closed after."""
    pair = (PtyPort(raw=False), PtyPort(raw=True))
    try:
        yield pair
    finally:
        for p in pair:
            p.close()
