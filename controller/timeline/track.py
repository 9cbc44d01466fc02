"""A track: clips placed at start times, played one at a time (a later clip takes over from an earlier one).

Each placed clip starts from the pose the track had at its start time (the previous clip's value there,
or its end pose if it had finished and holds), so a sequence "starts from wherever the face is" and a
clip started mid-way through another continues without a jump. Sampling is a pure function of time.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from servoface.controller.errors import TimelineError
from servoface.controller.timeline.clip import Clip, Pose


@dataclass(frozen=True)
class Placed:
    """A clip on a track from ``start_s``; ``from_pose`` overrides where it starts (None = the track)."""

    start_s: float
    clip: Clip
    from_pose: Mapping[str, float] | None = None

    @property
    def end_s(self) -> float:
        return self.start_s + self.clip.duration_s


class Track:
    """Placed clips on one named track (e.g. "face", "gesture", "speech")."""

    uses_below = False
    changes: ClassVar[int] = 0  # counts every track's changes (add, clear): what `Timeline.is_playing` keys on

    def __init__(self, name: str, initial_pose: Pose | None = None) -> None:
        self.name = name
        self.initial_pose: dict[str, float] = dict(initial_pose or {})
        self._items: list[Placed] = []
        self._starts: list[float] = []
        self._froms: list[dict[str, float]] = []

    @property
    def items(self) -> tuple[Placed, ...]:
        return tuple(self._items)

    def add(self, start_s: float, clip: Clip, from_pose: Pose | None = None) -> Placed:
        """Place ``clip`` at ``start_s`` (clips at the same start keep insertion order; the last wins)."""
        if isinstance(start_s, bool) or not isinstance(start_s, int | float) or not math.isfinite(start_s):
            raise TimelineError(f"track {self.name}: start time must be a finite number of seconds, got {start_s!r}")
        placed = Placed(float(start_s), clip, None if from_pose is None else dict(from_pose))
        index = bisect.bisect_right(self._starts, placed.start_s)
        self._items.insert(index, placed)
        self._starts.insert(index, placed.start_s)
        self._recompute(index)
        Track.changes += 1
        return placed

    def clear(self) -> None:
        self._items.clear()
        self._starts.clear()
        self._froms.clear()
        Track.changes += 1

    def _recompute(self, first: int) -> None:
        del self._froms[first:]
        for i in range(first, len(self._items)):
            item = self._items[i]
            if item.from_pose is not None:
                self._froms.append(dict(item.from_pose))
            elif i == 0:
                self._froms.append(dict(self.initial_pose))
            else:
                self._froms.append(self._state(i - 1, item.start_s))

    def _state(self, i: int, t_s: float) -> dict[str, float]:
        item = self._items[i]
        local = t_s - item.start_s
        if local < item.clip.duration_s:
            return item.clip.sample(local, self._froms[i])
        return item.clip.end_pose(self._froms[i]) if item.clip.holds else {}

    def active_index(self, t_s: float) -> int | None:
        """Index of the clip in charge at ``t_s`` (None before the first)."""
        i = bisect.bisect_right(self._starts, t_s) - 1
        return None if i < 0 else i

    def sample(self, t_s: float, below: Pose | None = None) -> dict[str, float]:
        """The track's AUs at ``t_s``; before its first clip, ``initial_pose`` (default {}: nothing)."""
        i = self.active_index(t_s)
        if i is None:
            return dict(self.initial_pose)
        return self._state(i, t_s)

    def is_playing(self, t_s: float) -> bool:
        i = self.active_index(t_s)
        return i is not None and t_s < self._items[i].end_s

    def playing_spans(self) -> list[tuple[float, float]]:
        """The times `is_playing` is true, as half-open spans ``[start, stop)`` in time order: clip i is in
        charge from its start to the next clip's start, and plays until its end."""
        spans = []
        for i, item in enumerate(self._items):
            stop = item.end_s if i + 1 == len(self._items) else min(item.end_s, self._starts[i + 1])
            if stop > item.start_s:
                spans.append((item.start_s, stop))
        return spans

    @property
    def end_s(self) -> float:
        return max((p.end_s for p in self._items), default=0.0)
