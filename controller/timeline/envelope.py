"""Onset / apex / offset envelopes: a gain 0 -> 1 -> hold -> 0 with easing on both ramps.

``Envelope(onset_s, apex_s, offset_s).gain(t)`` is the classic FACS timing shape (onset, apex, offset)
as a pure function of time since the envelope started. ``EnvelopeClip`` scales a pose by that gain and is
used for gestures layered over the face (a brow flash) and by the blink generator.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

from servoface.controller.errors import TimelineError
from servoface.controller.timeline.easing import Easing, min_jerk


def _check_duration(value: float, name: str, *, allow_zero: bool = True) -> float:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise TimelineError(f"{name}: expected a finite duration in seconds {bound}, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Envelope:
    """Gain over time: rises over ``onset_s``, holds 1 for ``apex_s``, falls over ``offset_s``."""

    onset_s: float
    apex_s: float
    offset_s: float
    easing: Easing = min_jerk
    offset_easing: Easing | None = None  # None = same as ``easing``

    def __post_init__(self) -> None:
        _check_duration(self.onset_s, "onset_s")
        _check_duration(self.apex_s, "apex_s")
        _check_duration(self.offset_s, "offset_s")

    @property
    def duration_s(self) -> float:
        return self.onset_s + self.apex_s + self.offset_s

    def gain(self, t_s: float) -> float:
        """Gain in [0, 1] at ``t_s`` seconds after the envelope starts (0 outside it)."""
        if t_s < 0.0 or t_s >= self.duration_s:
            return 0.0
        if t_s < self.onset_s:
            return self.easing(t_s / self.onset_s)
        t_off = t_s - self.onset_s - self.apex_s
        if t_off < 0.0:
            return 1.0
        fall = self.offset_easing or self.easing
        return 1.0 - fall(t_off / self.offset_s)


@dataclass(frozen=True)
class EnvelopeClip:
    """A pose scaled by an envelope: ``sample(t) = gain(t) * pose``. Ignores the face it starts from."""

    pose: Mapping[str, float]
    envelope: Envelope
    name: str = "envelope"
    holds: bool = field(default=False, init=False)  # contributes nothing once finished

    def targets(self) -> Iterator[tuple[str, float]]:
        yield from self.pose.items()

    @property
    def duration_s(self) -> float:
        return self.envelope.duration_s

    def sample(self, t_s: float, from_pose: Mapping[str, float]) -> dict[str, float]:
        g = self.envelope.gain(t_s)
        return {au: g * v for au, v in self.pose.items()}

    def end_pose(self, from_pose: Mapping[str, float]) -> dict[str, float]:
        return {}


def check_duration(value: float, name: str, *, allow_zero: bool = True) -> float:
    """Public alias used by other timeline modules and the script loader."""
    return _check_duration(value, name, allow_zero=allow_zero)
