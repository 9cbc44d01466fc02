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
        if not raw:
            self.port._raw_read = self.port._raw_write = False  # pyserial's own read and write, the reference

    def write(self, packet: Any) -> tuple[str, Any]:
        """``writePort(packet)``'s result, or its error's type name and message."""
        try:
            return "ok", self.port.writePort(packet)
        except Exception as err:
            return type(err).__name__, str(err)

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

    def drain(self) -> bytes:
        """Everything written so far, as the far end reads it."""
        out = b""
        os.set_blocking(self.master, False)
        deadline = time.monotonic() + 0.05
        while time.monotonic() < deadline:
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
