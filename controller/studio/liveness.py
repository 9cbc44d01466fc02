"""Which browsers are still there: the app-level heartbeat (API.md "Heartbeat").

A closed tab closes its WebSocket at once; a network that dies silently does not (TCP notices after
seconds, the WebSocket ping after ~4 s). So the page sends ``{"type": "heartbeat"}`` every 0.25 s, and a
socket that has sent one is *armed*: when nothing at all has arrived on it for ``timeout_s`` (1 s) it is
*silent*, exactly as if it had closed, though the socket stays open. When the last live socket goes
(closed or silent) ``on_last_gone(reason)`` is called once; the studio then eases to neutral unless
"hold" is on. A silent socket that speaks again is live again but moves nothing by itself: the head stays
where the drop put it until the user acts (any motion message). A socket that never sent a heartbeat (a
script, a test client) is judged by its close only, as before.

Times are ``time.monotonic`` (the host's, not the service clock): the question is when bytes arrived.

Silence counts only while this process runs: when the watchdog wakes more than ``STALL_S`` late (the
process descheduled or starved on a loaded machine), heartbeats may be sitting unread in the socket
buffers, so the time it did not run is not held against the sockets (`excuse_stall`). A dead browser is
still found within ``timeout_s`` of the time the server was awake to hear it, and at most
``EXCUSE_LIMIT`` × ``timeout_s`` of stalls is excused per silence (a machine so loaded that every wake is
late still finds a dead browser, within ``timeout_s`` × (1 + ``EXCUSE_LIMIT``)); a stalled server cannot move
the head meanwhile either (its loop is in this process)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

HEARTBEAT_INTERVAL_S = 0.25  # what the page sends (documented; the server does not depend on it)
HEARTBEAT_TIMEOUT_S = 0.8  # nothing heard for this long (3 heartbeats) on an armed socket: gone; ease starts < 1 s
WATCH_PERIOD_S = 0.05
STALL_S = 0.1  # the watchdog waking this much later than its period: the process did not run (`excuse_stall`)
EXCUSE_LIMIT = 2.0  # at most this many timeouts of stalls excused per silence of a socket


@dataclass
class _Socket:
    last_heard_s: float
    armed: bool = False
    silent: bool = False
    busy: int = 0  # messages being handled: a slow handler is not a silent browser
    excused_s: float = 0.0  # stall time excused since it was last heard (`Liveness.excuse_stall`)


class Liveness:
    """See the module docstring. Thread-safe; the watchdog is a daemon thread of its own."""

    def __init__(
        self,
        on_last_gone: Callable[[str], None],
        *,
        timeout_s: float = HEARTBEAT_TIMEOUT_S,
        clock: Callable[[], float] = time.monotonic,
        watch: bool = True,
    ) -> None:
        """``watch=False``: no watchdog thread (call :meth:`check` yourself, e.g. with a manual clock)."""
        self.on_last_gone = on_last_gone
        self.timeout_s = float(timeout_s)
        self.clock = clock
        self._sockets: dict[int, _Socket] = {}
        self._next = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="studio-heartbeat", daemon=True)
        if watch:
            self._thread.start()

    # -- counts ------------------------------------------------------------------------------------
    @property
    def connected(self) -> int:
        with self._lock:
            return len(self._sockets)

    @property
    def live(self) -> int:
        with self._lock:
            return sum(not s.silent for s in self._sockets.values())

    @property
    def silent(self) -> int:
        with self._lock:
            return sum(s.silent for s in self._sockets.values())

    # -- events from the sockets -------------------------------------------------------------------
    def joined(self) -> int:
        with self._lock:
            self._next += 1
            self._sockets[self._next] = _Socket(self.clock())
            return self._next

    def heard(self, key: int, *, heartbeat: bool = False, busy: int = 0) -> None:
        """Something arrived on socket ``key`` (``busy`` +1 / -1 around handling it)."""
        with self._lock:
            s = self._sockets.get(key)
            if s is None:
                return
            s.last_heard_s = self.clock()
            s.excused_s = 0.0
            s.armed = s.armed or heartbeat
            s.silent = False
            s.busy = max(0, s.busy + busy)

    def left(self, key: int) -> None:
        with self._lock:
            gone = self._sockets.pop(key, None)
            last = gone is not None and not gone.silent and not any(not s.silent for s in self._sockets.values())
        if last:
            self.on_last_gone("closed")

    # -- the watchdog ------------------------------------------------------------------------------
    def check(self) -> bool:
        """Mark armed sockets silent past the timeout; True when that made the last live one go."""
        now = self.clock()
        with self._lock:
            was_live = any(not s.silent for s in self._sockets.values())
            for s in self._sockets.values():
                if s.armed and not s.silent and not s.busy and now - s.last_heard_s > self.timeout_s:
                    s.silent = True
            gone = was_live and not any(not s.silent for s in self._sockets.values())
        if gone:
            self.on_last_gone("silent")
        return gone

    def excuse_stall(self, stalled_s: float) -> None:
        """The process did not run for ``stalled_s`` (the watchdog woke that late): each live socket's last
        heard time moves forward by it (never past now, and by at most ``EXCUSE_LIMIT`` timeouts in all
        since it was last heard), so that time is not counted as its silence. Nothing below ``STALL_S``
        (ordinary wake-up jitter)."""
        if not stalled_s > STALL_S:
            return
        now = self.clock()
        limit_s = EXCUSE_LIMIT * self.timeout_s
        with self._lock:
            for s in self._sockets.values():
                if not s.silent:
                    excuse_s = max(0.0, min(stalled_s, limit_s - s.excused_s))
                    s.excused_s += excuse_s
                    s.last_heard_s = min(now, s.last_heard_s + excuse_s)

    def watch_step(self, last_s: float) -> float:
        """One wake of the watchdog, ``last_s`` the clock at the one before: a late wake excused
        (`excuse_stall`), then `check`; returns the clock now."""
        now = self.clock()
        self.excuse_stall(now - last_s - WATCH_PERIOD_S)
        self.check()
        return now

    def _watch(self) -> None:
        last_s = self.clock()
        while not self._stop.wait(WATCH_PERIOD_S):
            try:
                last_s = self.watch_step(last_s)
            except Exception:  # noqa: BLE001 - the watchdog must outlive a failing callback
                last_s = self.clock()

    def close(self) -> None:
        self._stop.set()
