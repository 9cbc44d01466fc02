"""Barker's timing model (muscle-models.md §2): pose -> movement -> expression -> sequence.

- A **pose** is a set of AU intensities (a mapping; AUs not named are 0 — a pose is complete).
- A **movement** is a pose plus its share of the expression's duration; the pose is *reached* at the end
  of its share.
- An **expression** is a duration plus ordered movements whose shares sum to 1 (100 %).
- A **sequence** plays expressions in turn; the first movement starts from wherever the face is.

Barker interpolates piecewise-linearly; here each movement may also name an easing (default linear, so
the golden 2.34 s example is reproduced exactly). Onset/apex/offset is :meth:`Expression.envelope`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from servoface.controller.errors import FrameError, TimelineError
from servoface.controller.frame import validate_aus
from servoface.controller.timeline.clip import ChannelClip, Key, SequenceClip
from servoface.controller.timeline.easing import Easing, linear, min_jerk
from servoface.controller.timeline.envelope import check_duration

SHARE_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Movement:
    """Reach ``pose`` at the end of ``share`` (0..1) of the expression's duration, with ``easing``."""

    pose: Mapping[str, float]
    share: float
    easing: Easing = linear

    def __post_init__(self) -> None:
        ok = isinstance(self.share, int | float) and not isinstance(self.share, bool) and math.isfinite(self.share)
        if not ok or not 0.0 <= self.share <= 1.0:
            raise TimelineError(f"share: expected a fraction 0..1 of the expression's duration, got {self.share!r}")
        try:
            object.__setattr__(self, "pose", validate_aus(self.pose, where="pose"))
        except FrameError as err:
            raise TimelineError(str(err)) from err


@dataclass(frozen=True)
class Expression:
    """Duration plus ordered movements whose shares sum to 1."""

    name: str
    duration_s: float
    movements: tuple[Movement, ...]

    def __post_init__(self) -> None:
        check_duration(self.duration_s, f"{self.name}.duration_s", allow_zero=False)
        object.__setattr__(self, "movements", tuple(self.movements))
        if not self.movements:
            raise TimelineError(f"{self.name}.movements: expected at least one movement")
        total = sum(m.share for m in self.movements)
        if abs(total - 1.0) > SHARE_TOLERANCE:
            shares = ", ".join(f"{m.share:g}" for m in self.movements)
            raise TimelineError(f"{self.name}.movements: shares must sum to 1 (100 %), got {total:g} ({shares})")

    @classmethod
    def from_percent(
        cls, name: str, duration_s: float, parts: Sequence[tuple[float, Mapping[str, float]]]
    ) -> Expression:
        """Build from ``[(percent, pose), ...]`` as Barker writes it (10 % P1 + 80 % P2 + 10 % P3)."""
        return cls(name, duration_s, tuple(Movement(pose, pct / 100.0) for pct, pose in parts))

    @classmethod
    def envelope(
        cls,
        name: str,
        pose: Mapping[str, float],
        onset_s: float,
        apex_s: float,
        offset_s: float,
        easing: Easing = min_jerk,
    ) -> Expression:
        """Onset / apex / offset as movements: reach ``pose``, hold it, return to neutral."""
        for value, label in ((onset_s, "onset_s"), (apex_s, "apex_s"), (offset_s, "offset_s")):
            check_duration(value, f"{name}.{label}")
        d = onset_s + apex_s + offset_s
        if d <= 0:
            raise TimelineError(f"{name}: onset_s + apex_s + offset_s must be > 0")
        return cls(
            name,
            d,
            (
                Movement(pose, onset_s / d, easing),
                Movement(pose, apex_s / d, linear),
                Movement({}, offset_s / d, easing),
            ),
        )

    def key_times_s(self) -> list[float]:
        """The time each movement's pose is reached (e.g. 0.234, 2.106, 2.34 s in Barker's example)."""
        times, acc = [], 0.0
        for m in self.movements:
            acc += m.share
            times.append(self.duration_s * min(acc, 1.0))
        times[-1] = self.duration_s
        return times

    def clip(self) -> ChannelClip:
        """Compile to per-AU keyframes that start from the face's pose at play time."""
        times = self.key_times_s()
        names: list[str] = []
        for m in self.movements:
            names += [au for au in m.pose if au not in names]
        channels = {
            au: (Key(0.0, None),)
            + tuple(Key(t, m.pose.get(au, 0.0), m.easing) for t, m in zip(times, self.movements, strict=True))
            for au in names
        }
        return ChannelClip(
            channels,
            self.duration_s,
            unlisted="to_zero",
            release_s=times[0],
            release_easing=self.movements[0].easing,
            name=self.name,
        )

    def scaled(self, duration_s: float) -> Expression:
        """The same movements over another duration (Barker: retime by scaling d)."""
        return Expression(self.name, duration_s, self.movements)


def sequence(expressions: Sequence[Expression | ChannelClip | SequenceClip], name: str = "sequence") -> SequenceClip:
    """Expressions in turn; the first starts from the face, each next from where the previous ended."""
    clips = tuple(e.clip() if isinstance(e, Expression) else e for e in expressions)
    return SequenceClip(clips, name=name)


def hold(pose: Mapping[str, float], duration_s: float, name: str = "hold") -> ChannelClip:
    """Cut to ``pose`` at once (AUs not in it to 0) and hold it for ``duration_s``."""
    return Expression(name, duration_s, (Movement(pose, 0.0), Movement(pose, 1.0))).clip()
