"""Pseudo-terminal transport: serves a chain on a Linux/macOS pty so any program (the stock SDK) can open it.

A background thread moves instruction bytes from the pty into the chain and writes reply bytes back once
they have arrived on the virtual wire. It is built to stay cheap and punctual on a loaded machine:

- one wake-up and one ``write`` per reply burst: the thread sleeps until the last byte of everything the
  servos are sending has arrived and hands it over in one write (a USB adapter also hands over frames, not
  bytes), holding the first byte at most ``MAX_HOLD_S`` (the FTDI default latency timer) if the burst keeps
  growing; a thread that wakes late writes whatever has arrived by then, so reply timing never depends on
  being scheduled at an exact instant, only on being scheduled inside the client's reply window;
- back-pressure: it reads from the pty only as many bytes as fit ahead of the wire
  (``ServoChain.tx_buffer_bytes``), so a client writing faster than the baud blocks in ``write()`` once
  the kernel's pty buffer is full, as on a real port, instead of queueing seconds of traffic;
- the host's baud is read from the pty's termios (what the client set) when bytes arrive, so a client at
  the wrong baud gets silence, as on a real bus;
- real-time scheduling where allowed: on a loaded machine the pty's latency is the serving thread's
  scheduling delay (measured here with 8 busy processes on 2 cores: a plain echo server at normal priority
  misses 30 ms on 12 % of round trips, at SCHED_RR on none), so the thread asks for ``SCHED_RR`` at
  priority ``RT_PRIORITY`` (it sleeps almost always and uses ~0.4 ms of CPU per 24-servo cycle). Without
  permission (not root, no CAP_SYS_NICE, ``ulimit -r`` 0) it stays at normal priority and says so in
  ``PtyServer.priority``.
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
RT_PRIORITY = 10  # SCHED_RR priority of the serving thread (1..99; low, above every normal process)
MAX_HOLD_S = 0.016  # longest a reply byte waits for the rest of its burst (FTDI default latency timer)
LATE_S = 0.010  # a burst handed over later than this after it was due counts as late (stats only)
READ_CHUNK = 65536


def _speed_table() -> dict[int, int]:
    table: dict[int, int] = {}
    for name in dir(termios):
        if name.startswith("B") and name[1:].isdigit():
            table[getattr(termios, name)] = int(name[1:])
    return table


_SPEEDS = _speed_table()


class PtyServer:
    """Owns the pty pair and the serving thread; ``path`` is the slave device to hand to clients."""

    def __init__(self, chain: ServoChain, *, realtime: bool = True) -> None:
        self._chain = chain
        self._realtime = realtime
        self.priority = "normal (not started)"
        self._started = threading.Event()
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
        self.wakeups = 0  # select() calls (for the benchmark's cost figure)
        self.writes = 0  # write() calls to the pty
        self.bursts = 0  # reply bursts handed over
        self.late_bursts = 0  # ... of which later than LATE_S after their last byte was due
        self.max_late_s = 0.0

    def start(self) -> None:
        self._thread.start()
        self._started.wait(2.0)

    def _raise_priority(self) -> str:
        """Ask for real-time round-robin scheduling for this thread; a description of what we got."""
        if not self._realtime:
            return "normal (real-time scheduling not requested)"
        setter = getattr(os, "sched_setscheduler", None)
        if setter is None:
            return "normal (no real-time scheduling on this system)"
        try:
            setter(0, os.SCHED_RR, os.sched_param(RT_PRIORITY))  # 0: the calling thread on Linux
        except (OSError, ValueError) as err:
            return (
                f"normal (real-time scheduling refused: {err}; allow it with `ulimit -r {RT_PRIORITY}` or CAP_SYS_NICE)"
            )
        return f"real-time (SCHED_RR {RT_PRIORITY})"

    def host_baud(self) -> int:
        """The baud the client set on the pty (0 if unknown)."""
        try:
            speed = termios.tcgetattr(self._slave)[5]
        except termios.error:
            return 0
        return _SPEEDS.get(speed, int(speed) if isinstance(speed, int) and speed > 4096 else 0)

    def _timing(self, baud: int) -> tuple[float, int | None, float | None]:
        """(select timeout, bytes we may read now or None for any, when to hand over replies or None)."""
        chain = self._chain
        now = chain.time_s
        timeout = IDLE_WAIT_S
        deliver_at = None
        burst = chain.rx_burst_times_s()
        if burst is not None:
            first, last = burst
            deliver_at = min(last, first + MAX_HOLD_S)
            timeout = min(timeout, max(0.0, deliver_at - now))
        room = chain.tx_room_bytes(baud)
        low = max(1, chain.tx_buffer_bytes // 4)  # read in chunks of at least this (fewer wake-ups)
        if room is not None and room < low:
            wait_s = chain.tx_backlog_s() - (chain.tx_buffer_bytes - low) * 10.0 / baud
            timeout = min(timeout, max(0.0, wait_s))
            room = 0
        return timeout, room, deliver_at

    def _serve(self) -> None:
        chain = self._chain
        master = self._master
        wake_r = self._wake_r
        self.priority = self._raise_priority()
        self._started.set()
        baud = self.host_baud()
        pending = b""  # reply bytes the pty could not take yet
        try:
            while not self._stop.is_set():
                timeout, room, deliver_at = self._timing(baud)
                readers = [wake_r] if room is not None and room <= 0 else [master, wake_r]
                writers = [master] if pending else []
                if pending:
                    timeout = min(timeout, IDLE_WAIT_S)
                self.wakeups += 1
                readable, writable, _ = select.select(readers, writers, [], timeout)
                if wake_r in readable:
                    break
                if master in readable:
                    try:
                        data = os.read(master, READ_CHUNK if room is None else max(1, room))
                    except (BlockingIOError, InterruptedError):
                        data = b""
                    except OSError:
                        data = b""
                    if data:
                        baud = self.host_baud()
                        chain.host_write(data, baud)  # replies it schedules arrive later: next round
                if deliver_at is not None and (now := chain.time_s) >= deliver_at:
                    pending += chain.host_read(1 << 20)
                    late_s = now - deliver_at
                    self.bursts += 1
                    self.max_late_s = max(self.max_late_s, late_s)
                    if late_s > LATE_S:
                        self.late_bursts += 1
                if pending:
                    try:
                        written = os.write(master, pending)
                    except BlockingIOError:
                        written = 0
                    self.writes += 1
                    pending = pending[written:]
        except BaseException as err:  # noqa: BLE001 - reported through .error, the thread must not die silently
            self.error = err

    def stats(self) -> str:
        """One line on the serving thread's punctuality (for logs and benchmarks)."""
        return (
            f"{self.bursts} reply bursts, {self.late_bursts} handed over more than {LATE_S * 1e3:g} ms late, "
            f"latest {self.max_late_s * 1e3:.1f} ms; {self.wakeups} wake-ups, {self.writes} writes"
        )

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
