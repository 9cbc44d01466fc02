"""Pseudo-terminal transport: serves a chain on a Linux/macOS pty so any program (the stock SDK) can open it.

A background thread moves instruction bytes from the pty into the chain and writes reply bytes back when
their wire arrival time has come. The host's baud is read from the pty's termios (what the client set), so
a client at the wrong baud gets silence, as on a real bus.
"""

from __future__ import annotations

import os
import select
import termios
import threading
import tty
from typing import TYPE_CHECKING

from servoface.hardware.emulator.errors import EmulatorError

if TYPE_CHECKING:
    from servoface.hardware.emulator.chain import ServoChain

IDLE_WAIT_S = 0.05


def _speed_table() -> dict[int, int]:
    table: dict[int, int] = {}
    for name in dir(termios):
        if name.startswith("B") and name[1:].isdigit():
            table[getattr(termios, name)] = int(name[1:])
    return table


_SPEEDS = _speed_table()


class PtyServer:
    """Owns the pty pair and the serving thread; ``path`` is the slave device to hand to clients."""

    def __init__(self, chain: ServoChain) -> None:
        self._chain = chain
        try:
            self._master, self._slave = os.openpty()
        except OSError as err:
            raise EmulatorError(f"cannot open a pseudo-terminal for the servo chain: {err}") from err
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        os.set_blocking(self._master, False)
        self._wake_r, self._wake_w = os.pipe()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"servo-chain-pty {self.path}", daemon=True)
        self.error: BaseException | None = None

    def start(self) -> None:
        self._thread.start()

    def host_baud(self) -> int:
        """The baud the client set on the pty (0 if unknown)."""
        try:
            speed = termios.tcgetattr(self._slave)[5]
        except termios.error:
            return 0
        return _SPEEDS.get(speed, int(speed) if isinstance(speed, int) and speed > 4096 else 0)

    def _serve(self) -> None:
        chain = self._chain
        master = self._master
        try:
            while not self._stop.is_set():
                due = chain.next_reply_time_s()
                if due is None:
                    timeout = IDLE_WAIT_S
                else:
                    timeout = max(0.0, min(IDLE_WAIT_S, due - chain.time_s))
                readable, _, _ = select.select([master, self._wake_r], [], [], timeout)
                if self._wake_r in readable:
                    break
                if master in readable:
                    try:
                        data = os.read(master, 65536)
                    except (BlockingIOError, InterruptedError):
                        data = b""
                    except OSError:
                        data = b""
                    if data:
                        chain.host_write(data, self.host_baud())
                out = chain.host_read(1 << 20)
                while out:
                    try:
                        written = os.write(master, out)
                    except BlockingIOError:
                        select.select([], [master], [], IDLE_WAIT_S)
                        continue
                    out = out[written:]
        except BaseException as err:  # noqa: BLE001 - reported through .error, the thread must not die silently
            self.error = err

    def stop(self) -> None:
        """Stop serving and close the pty (clients see the device vanish)."""
        self._stop.set()
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave, self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
