"""Stop requests from signals: SIGINT (Ctrl-C), SIGTERM (``kill``, a service manager), SIGHUP (the terminal
closed), installed by the CLI around a whole run (`StopSignals`, a context manager, main thread only).

- The first signal is a **stop request**: every loop running under ``stop_on_sigint`` stops at its next
  frame and the run goes down the one stop path (`servoface.controller.safe_stop`): ease to neutral, then
  torque off.
- A second signal (Ctrl-C twice, or any two) is a **hurry**: the slow easing is dropped and the head goes
  straight to neutral as fast as the gate's caps allow (at most ``safe_stop.HURRY_S``), then torque goes off
  on every servo — torque is never cut mid-pose, and nothing is cut half way.
- Handlers never raise while the bus may be in use. Only inside an `interruptible()` block (work with
  torque off and no bus traffic: loading files, building the gate's tables at start-up) does a signal raise
  `StopRequested` (a KeyboardInterrupt) at once, so a long start-up ends promptly.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any, Protocol

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class StopRequested(KeyboardInterrupt):
    """A stop signal arrived while the run was interruptible (start-up); ``signum`` names it."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(f"stopped by {signal.Signals(signum).name}")


class Stoppable(Protocol):
    def stop(self) -> None: ...


_active: StopSignals | None = None


def active() -> StopSignals | None:
    """The installed `StopSignals`, if a CLI (or a service) installed one."""
    return _active


class StopSignals:
    """Collects stop signals for one run; see the module docstring."""

    def __init__(self, signals: tuple[int, ...] = SIGNALS) -> None:
        self.signals = signals
        self.received: list[int] = []
        self._loops: list[Stoppable] = []
        self._previous: dict[int, Any] = {}
        self._interruptible = 0
        self._lock = threading.Lock()

    # -- state ----------------------------------------------------------------------------------------
    @property
    def requested(self) -> bool:
        return bool(self.received)

    @property
    def hurry(self) -> bool:
        """A second signal: straight to neutral at the gate's caps, then torque off (see the module docstring)."""
        return len(self.received) >= 2

    @property
    def first(self) -> int | None:
        return self.received[0] if self.received else None

    @property
    def name(self) -> str | None:
        return None if self.first is None else signal.Signals(self.first).name

    def exit_code(self) -> int | None:
        """128 + the first signal's number (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), None if none came."""
        return None if self.first is None else 128 + self.first

    # -- signals --------------------------------------------------------------------------------------
    def request(self, signum: int) -> None:
        """What a handler does (also callable from code: a service's stop command)."""
        with self._lock:
            self.received.append(signum)
            loops = list(self._loops)
        for loop in loops:
            loop.stop()

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        self.request(signum)
        if self._interruptible and len(self.received) >= 1:
            raise StopRequested(signum)

    def install(self) -> StopSignals:
        global _active
        if threading.current_thread() is not threading.main_thread():
            return self  # signals reach the main thread only; a run in another thread keeps its caller's handling
        for s in self.signals:
            self._previous[s] = signal.signal(s, self._handler)
        _active = self
        return self

    def restore(self) -> None:
        global _active
        for s, handler in self._previous.items():
            signal.signal(s, handler)
        self._previous.clear()
        if _active is self:
            _active = None

    def __enter__(self) -> StopSignals:
        return self.install()

    def __exit__(self, *exc: object) -> None:
        self.restore()

    # -- loops and regions ----------------------------------------------------------------------------
    @contextmanager
    def watching(self, loop: Stoppable) -> Iterator[None]:
        """``loop.stop()`` on the next signal (at once if one already came)."""
        with self._lock:
            self._loops.append(loop)
            already = self.requested
        if already:
            loop.stop()
        try:
            yield
        finally:
            with self._lock:
                self._loops.remove(loop)

    @contextmanager
    def interruptible_block(self) -> Iterator[None]:
        if self.requested and self.first is not None:
            raise StopRequested(self.first)
        self._interruptible += 1
        try:
            yield
        finally:
            self._interruptible -= 1


@contextmanager
def interruptible() -> Iterator[None]:
    """A block with torque off and no bus traffic: a stop signal raises `StopRequested` at once (and at
    entry if one already came). Without installed `StopSignals` it does nothing."""
    signals = _active
    if signals is None:
        yield
        return
    with signals.interruptible_block():
        yield


def raise_if_requested() -> None:
    """`StopRequested` if a stop signal already came (call before switching torque on)."""
    signals = _active
    if signals is not None and signals.first is not None:
        raise StopRequested(signals.first)
