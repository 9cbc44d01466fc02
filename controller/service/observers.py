"""Observers: bounded, drop-oldest queues the loop thread offers items to without ever waiting.

``service.subscribe(kind, rate_hz=..., maxlen=...)`` returns a :class:`Subscription`. Kinds:

- ``"frame"``: a :class:`FrameSummary` per frame (verdict, reasons, stage timings, lateness);
- ``"trace"``: the full :class:`~servoface.controller.pipeline.FrameTrace` per frame;
- ``"telemetry"``: the driver's :class:`~servoface.hardware.snapshot.ChainSnapshot` (positions, load,
  temperatures, faults) after a frame;
- ``"fault"``: every :class:`~servoface.hardware.snapshot.FaultEvent` the driver reports, plus the service's
  own (e-stop, bus failure) as :class:`ServiceEvent`;
- ``"playback"``: a :class:`~servoface.controller.service.handles.PlaybackEvent` per command status change.

``rate_hz`` thins frame / trace / telemetry items to at most that rate (service time; None = every
frame); events (fault, playback) are never thinned. When the queue is full the oldest item is dropped and
counted (``dropped``). The loop appends with a lock-free deque and only *tries* to wake the reader, so a
reader that is slow, stalled or holding its own locks never delays a frame.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Generic, Literal, TypeVar

from servoface.controller.service.errors import ServiceError

Kind = Literal["frame", "trace", "telemetry", "fault", "playback"]
KINDS: tuple[Kind, ...] = ("frame", "trace", "telemetry", "fault", "playback")
_THINNED = frozenset({"frame", "trace", "telemetry"})
MAX_QUEUE = 1_000_000  # the longest queue a subscription may ask for
T = TypeVar("T")


@dataclass(frozen=True)
class FrameSummary:
    """One frame as an observer sees it (small, copied)."""

    index: int
    t_s: float  # service time the frame was scheduled for
    verdict: str
    checks: tuple[str, ...]
    reasons: tuple[str, ...]
    timings_ms: dict[str, float]
    late_s: float
    skipped_before: int  # frames the loop skipped just before this one (their slot had passed)

    def as_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "t_s": round(self.t_s, 6),
            "verdict": self.verdict,
            "checks": list(self.checks),
            "reasons": list(self.reasons),
            "timings_ms": {k: round(v, 4) for k, v in self.timings_ms.items()},
            "late_s": round(self.late_s, 6),
            "skipped_before": self.skipped_before,
        }


@dataclass(frozen=True)
class ServiceEvent:
    """A fault-level event of the service itself: ``kind`` e.g. "estop", "estop_cleared", "bus_failure"."""

    t_s: float
    kind: str
    detail: str = ""


class Subscription(Generic[T]):
    """A bounded queue of observed items. Read with ``get``, ``drain`` or iteration; ``close`` when done."""

    def __init__(self, kind: Kind, maxlen: int, rate_hz: float | None, hub: ObserverHub) -> None:
        self.kind = kind
        self.maxlen = maxlen
        self.rate_hz = rate_hz
        self.dropped = 0
        self.offered = 0
        self._items: deque[T] = deque(maxlen=maxlen)
        self._cond = threading.Condition()
        self._hub = hub
        self._next_s = float("-inf")
        self.closed = False

    def __repr__(self) -> str:
        return f"<Subscription {self.kind} {len(self._items)}/{self.maxlen} dropped={self.dropped}>"

    def __len__(self) -> int:
        return len(self._items)

    # -- loop side (never blocks) -------------------------------------------------------------------
    def _due(self, t_s: float) -> bool:
        if self.rate_hz is None or self.kind not in _THINNED:
            return True
        if t_s + 1e-6 < self._next_s:
            return False
        self._next_s = t_s + 1.0 / self.rate_hz
        return True

    def _offer(self, item: T) -> None:
        self.offered += 1
        if len(self._items) >= self.maxlen:
            self.dropped += 1
        self._items.append(item)  # deque(maxlen) drops the oldest itself; append is atomic
        if self._cond.acquire(blocking=False):  # wake a waiting reader if we can; it polls anyway
            try:
                self._cond.notify_all()
            finally:
                self._cond.release()

    # -- reader side --------------------------------------------------------------------------------
    def get(self, timeout_s: float | None = None) -> T | None:
        """The oldest item, waiting up to ``timeout_s`` (None = until one comes or the subscription is
        closed); None on timeout or when closed and empty."""
        deadline = None if timeout_s is None else time.monotonic() + max(0.0, timeout_s)
        with self._cond:
            while True:
                try:
                    return self._items.popleft()
                except IndexError:
                    pass
                if self.closed:
                    return None
                left = 0.05 if deadline is None else min(0.05, deadline - time.monotonic())
                if left <= 0:
                    return None
                self._cond.wait(left)

    def drain(self) -> list[T]:
        """Every queued item, oldest first, without waiting."""
        out: list[T] = []
        while True:
            try:
                out.append(self._items.popleft())
            except IndexError:
                return out

    def __iter__(self) -> Iterator[T]:
        while True:
            item = self.get()
            if item is None:
                return
            yield item

    def close(self) -> None:
        """Stop receiving (queued items stay readable)."""
        self.closed = True
        self._hub._remove(self)

    def __enter__(self) -> Subscription[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ObserverHub:
    """The service's subscriptions by kind (subscribe/close from any thread; offered by the loop)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._by_kind: dict[str, tuple[Subscription[Any], ...]] = {k: () for k in KINDS}

    def subscribe(self, kind: str, *, rate_hz: float | None = None, maxlen: int = 256) -> Subscription[Any]:
        if kind not in KINDS:
            raise ServiceError(f"subscribe: kind must be one of {list(KINDS)}, got {kind!r}")
        if isinstance(maxlen, bool) or not isinstance(maxlen, int) or not 1 <= maxlen <= MAX_QUEUE:
            raise ServiceError(f"subscribe: maxlen must be an integer 1..{MAX_QUEUE}, got {maxlen!r}")
        if rate_hz is not None and (
            isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float) or not 0 < rate_hz <= 10_000
        ):
            raise ServiceError(f"subscribe: rate_hz must be a rate 0 < r <= 10000 Hz or None, got {rate_hz!r}")
        sub: Subscription[Any] = Subscription(kind, maxlen, None if rate_hz is None else float(rate_hz), self)
        with self._lock:
            self._by_kind[kind] = (*self._by_kind[kind], sub)
        return sub

    def _remove(self, sub: Subscription[Any]) -> None:
        with self._lock:
            self._by_kind[sub.kind] = tuple(s for s in self._by_kind[sub.kind] if s is not sub)

    def wants(self, kind: Kind) -> bool:
        return bool(self._by_kind[kind])

    def offer(self, kind: Kind, item: Any, t_s: float = 0.0) -> None:
        for sub in self._by_kind[kind]:  # a tuple: subscribe/close swap it whole, no lock needed here
            if sub._due(t_s):
                sub._offer(item)

    def offer_lazy(self, kind: Kind, make: Any, t_s: float) -> None:
        """Offer ``make()`` to the subscribers due at ``t_s`` (built once, only if one is due)."""
        item = None
        for sub in self._by_kind[kind]:
            if sub._due(t_s):
                if item is None:
                    item = make()
                sub._offer(item)

    def close_all(self) -> None:
        with self._lock:
            subs = [s for group in self._by_kind.values() for s in group]
            self._by_kind = {k: () for k in KINDS}
        for sub in subs:
            sub.closed = True
