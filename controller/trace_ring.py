"""`TraceRing`: the newest frame traces in a bounded ring, with counts over every trace ever added.

A frame trace is ~4 KB; keeping all of them grew a 50 Hz run by ~0.75 GB an hour. The ring keeps the last
``maxlen`` (default `TRACE_RING_FRAMES`, one minute at 50 Hz) for inspection; verdict counts, frames and
bytes written cover the whole run; ``sink`` (e.g. a `TraceWriter` for ``--trace``) gets every trace as it
arrives, so a trace file holds the whole run without the process holding it.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Callable, Iterable, Iterator
from typing import IO, Any

TRACE_RING_FRAMES = 3000


class TraceRing:
    """List-like over the newest traces (index, iterate, ``len``); ``total`` counts every one added."""

    def __init__(
        self,
        items: Iterable[Any] = (),
        *,
        maxlen: int = TRACE_RING_FRAMES,
        sink: Callable[[Any], None] | None = None,
    ) -> None:
        self._ring: deque[Any] = deque(maxlen=maxlen)
        self.total = 0
        self.verdict_counts: Counter[str] = Counter()
        self.bytes_written = 0
        self.sink = sink
        self.extend(items)

    @property
    def maxlen(self) -> int | None:
        return self._ring.maxlen

    def append(self, trace: Any) -> None:
        self._ring.append(trace)
        self.total += 1
        self.verdict_counts[getattr(trace, "verdict", "")] += 1
        self.bytes_written += int(getattr(trace, "bytes_written", 0))
        if self.sink is not None:
            self.sink(trace)

    def extend(self, traces: Iterable[Any]) -> None:
        for trace in traces:
            self.append(trace)

    def __len__(self) -> int:
        return len(self._ring)

    def __iter__(self) -> Iterator[Any]:
        return iter(self._ring)

    def __getitem__(self, index: int) -> Any:
        return self._ring[index]

    def __bool__(self) -> bool:
        return bool(self._ring)

    def __repr__(self) -> str:
        return f"TraceRing({len(self._ring)} kept of {self.total}, maxlen={self._ring.maxlen})"


class TraceWriter:
    """Writes each trace as one JSON line as it comes (``--trace FILE``); text escaped to ASCII."""

    def __init__(self, fh: IO[str]) -> None:
        self.fh = fh
        self.count = 0

    def __call__(self, trace: Any) -> None:
        import json

        self.fh.write(json.dumps(trace.as_dict(), ensure_ascii=True) + "\n")
        self.count += 1
