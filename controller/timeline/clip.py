"""Clips: things a track plays. A clip is a pure function of time since it started and of the pose the
face was in when it started (``from_pose``), which is how a sequence "starts from wherever the face is".

- :class:`ChannelClip`: per-AU keyframes (``Key``); a key whose value is None means "the value the face
  had when the clip started". AUs the clip does not list either go to 0 along the first segment
  (``unlisted="to_zero"``: a Barker pose is complete) or keep their value (``"hold"``: DFACS events only
  change the AUs they name).
- :class:`SequenceClip`: clips in turn, each starting from the previous one's end pose.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Literal, Protocol

from servoface.controller.errors import TimelineError
from servoface.controller.timeline.easing import Easing, linear

Pose = Mapping[str, float]
Unlisted = Literal["to_zero", "hold"]


class Clip(Protocol):
    """What a :class:`~servoface.controller.timeline.track.Track` can play."""

    @property
    def name(self) -> str: ...

    @property
    def holds(self) -> bool:
        """True: after the end the track keeps ``end_pose``; False: it contributes nothing."""
        ...

    @property
    def duration_s(self) -> float: ...

    def sample(self, t_s: float, from_pose: Pose) -> dict[str, float]: ...

    def end_pose(self, from_pose: Pose) -> dict[str, float]: ...

    def targets(self) -> Iterator[tuple[str, float]]: ...


@dataclass(frozen=True)
class Key:
    """Reach ``value`` at ``t_s`` (clip-local), moving from the previous key with ``easing``.

    ``value`` None = the AU's value when the clip started.
    """

    t_s: float
    value: float | None
    easing: Easing = linear


def _value(key: Key, start: float) -> float:
    return start if key.value is None else key.value


@dataclass(frozen=True)
class ChannelClip:
    """Per-AU keyframe channels; keys sorted by time. See the module docstring for ``unlisted``."""

    channels: Mapping[str, tuple[Key, ...]]
    duration_s: float
    unlisted: Unlisted = "to_zero"
    release_s: float = 0.0  # length of the first segment, over which unlisted AUs go to 0
    release_easing: Easing = linear
    name: str = "clip"
    holds: bool = True
    _times: dict[str, list[float]] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for au, keys in self.channels.items():
            if not keys:
                raise TimelineError(f"{self.name}: channel {au} has no keys")
            times = [k.t_s for k in keys]
            if any(b < a for a, b in zip(times, times[1:], strict=False)):
                raise TimelineError(f"{self.name}: channel {au} keys are not in time order: {times}")
            self._times[au] = times

    def _channel(self, au: str, keys: tuple[Key, ...], t_s: float, start: float) -> float:
        times = self._times[au]
        i = bisect.bisect_right(times, t_s)
        if i == 0:
            return _value(keys[0], start)
        if i == len(keys):
            return _value(keys[-1], start)
        a, b = keys[i - 1], keys[i]
        span = b.t_s - a.t_s
        va = start if a.value is None else a.value  # (`_value` inline: per AU per frame)
        vb = start if b.value is None else b.value
        return va + (vb - va) * b.easing((t_s - a.t_s) / span)

    def sample(self, t_s: float, from_pose: Pose) -> dict[str, float]:
        out = {au: self._channel(au, keys, t_s, from_pose.get(au, 0.0)) for au, keys in self.channels.items()}
        for au, start in from_pose.items():
            if au in out:
                continue
            if self.unlisted == "hold":
                out[au] = start
            elif self.release_s <= 0.0:
                out[au] = 0.0
            else:
                out[au] = start * (1.0 - self.release_easing(t_s / self.release_s))
        return out

    def end_pose(self, from_pose: Pose) -> dict[str, float]:
        return self.sample(max(self.duration_s, self.release_s), from_pose)

    def targets(self) -> Iterator[tuple[str, float]]:
        for au, keys in self.channels.items():
            for key in keys:
                if key.value is not None:
                    yield au, key.value

    def onsets(self) -> dict[str, list[tuple[float, float, float]]]:
        """Per AU, the motions as (start_s, end_s, target) — every key that changes the value."""
        out: dict[str, list[tuple[float, float, float]]] = {}
        for au, keys in self.channels.items():
            moves = []
            for a, b in zip(keys, keys[1:], strict=False):
                if b.value is not None and (a.value is None or a.value != b.value) and b.t_s > a.t_s:
                    moves.append((a.t_s, b.t_s, b.value))
            out[au] = moves
        return out


@dataclass(frozen=True)
class SequenceClip:
    """Clips played one after another; the first starts from the face, each next from the previous end."""

    clips: tuple[ChannelClip | SequenceClip, ...]
    name: str = "sequence"
    holds: bool = True

    def __post_init__(self) -> None:
        if not self.clips:
            raise TimelineError(f"{self.name}: a sequence needs at least one expression")

    @property
    def duration_s(self) -> float:
        return sum(c.duration_s for c in self.clips)

    def starts_s(self) -> list[float]:
        """Start time of each clip within the sequence."""
        starts, t = [], 0.0
        for c in self.clips:
            starts.append(t)
            t += c.duration_s
        return starts

    def start_poses(self, from_pose: Pose) -> list[dict[str, float]]:
        """The pose each clip starts from, given where the sequence starts (cached per start pose)."""
        cache: dict[tuple[tuple[str, float], ...], list[dict[str, float]]]
        cache = self.__dict__.setdefault("_start_cache", {})
        key = tuple(sorted(from_pose.items()))
        starts = cache.get(key)
        if starts is None:
            starts = [dict(from_pose)]
            for clip in self.clips[:-1]:
                starts.append(clip.end_pose(starts[-1]))
            if len(cache) > 64:
                cache.clear()
            cache[key] = starts
        return starts

    def sample(self, t_s: float, from_pose: Pose) -> dict[str, float]:
        starts = self.start_poses(from_pose)
        offset = 0.0
        last = len(self.clips) - 1
        for i, clip in enumerate(self.clips):
            if t_s < offset + clip.duration_s or i == last:
                return clip.sample(t_s - offset, starts[i])
            offset += clip.duration_s
        return {}  # unreachable: the last clip always answers

    def end_pose(self, from_pose: Pose) -> dict[str, float]:
        pose: Pose = from_pose
        for clip in self.clips:
            pose = clip.end_pose(pose)
        return dict(pose)

    def targets(self) -> Iterator[tuple[str, float]]:
        for clip in self.clips:
            yield from clip.targets()
