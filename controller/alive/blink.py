"""Spontaneous blinks: a seeded random process, a pure function of time.

Inter-blink intervals are gamma distributed (shape ``shape`` = 2.5, mean ``mean_interval_s`` = 4 s, i.e.
about 15 blinks a minute, right-skewed like human spontaneous blinking) with a refractory floor
``min_interval_s`` = 0.8 s. Each blink lasts uniform ``duration_s`` = 0.15..0.30 s: the lid closes over the
first ``close_share`` = 40 % (minimum-jerk) and reopens over the rest. A blink is AU45 on the human face and
DFACS AU15 on the dog.

Merging with the face: the layer emits the blink AU; the blend rule ``max`` merges it with whatever the
expression already has (a half-closed lid blinks from half-closed and returns there). While the layers
below already close the lids (any of ``lid_aus`` >= ``suppress_at`` = 0.8, e.g. AU43 eyes closed) the
blink is suppressed (emits nothing).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from servoface.controller.errors import TimelineError
from servoface.controller.timeline.easing import min_jerk
from servoface.sim.rig import FaceType

BLINK_AU: dict[str, str] = {"human": "AU45", "dog": "AU15"}
LID_AUS: dict[str, tuple[str, ...]] = {
    "human": ("AU43", "AU45", "AU43L", "AU43R", "AU45L", "AU45R"),
    "dog": ("AU15", "AU15L", "AU15R", "AU4", "AU4L", "AU4R"),
}


@dataclass(frozen=True)
class BlinkConfig:
    mean_interval_s: float = 4.0
    shape: float = 2.5
    min_interval_s: float = 0.8
    min_duration_s: float = 0.15
    max_duration_s: float = 0.30
    close_share: float = 0.4
    amplitude: float = 1.0
    suppress_at: float = 0.8
    first_after_s: float = 0.5  # no blink in the first half second of a performance

    def __post_init__(self) -> None:
        checks = {
            "mean_interval_s": self.mean_interval_s > self.min_interval_s >= 0,
            "shape": self.shape > 0,
            "min_duration_s": 0 < self.min_duration_s <= self.max_duration_s,
            "max_duration_s": self.max_duration_s < self.min_interval_s or self.min_interval_s == 0,
            "close_share": 0 < self.close_share < 1,
            "amplitude": 0 < self.amplitude <= 1,
            "suppress_at": 0 < self.suppress_at <= 1,
            "first_after_s": self.first_after_s >= 0,
        }
        for name, ok in checks.items():
            value = getattr(self, name)
            if not ok or not math.isfinite(value):
                raise TimelineError(f"blink.{name}: value {value!r} is not allowed (see BlinkConfig)")


@dataclass
class Blink:
    """One blink: starts at ``start_s`` and lasts ``duration_s``."""

    start_s: float
    duration_s: float


@dataclass
class BlinkLayer:
    """The blink behaviour as a timeline layer: ``sample(t, below) -> {AU45: x}`` (or {})."""

    face_type: FaceType
    seed: int = 0
    config: BlinkConfig = field(default_factory=BlinkConfig)
    _blinks: list[Blink] = field(default_factory=list, init=False, repr=False)
    _starts: list[float] = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.face_type not in BLINK_AU:
            raise TimelineError(f"blink: face type must be 'human' or 'dog', got {self.face_type!r}")
        self._rng = np.random.default_rng(self.seed)
        self._below_aus = frozenset(LID_AUS[self.face_type])
        self._next_s = self.config.first_after_s + self._interval()

    @property
    def below_aus(self) -> frozenset[str]:
        """The AUs of the blend below that `sample` reads (`suppressed`): the timeline blends only those."""
        return self._below_aus

    @property
    def au(self) -> str:
        return BLINK_AU[self.face_type]

    def _interval(self) -> float:
        c = self.config
        scale = (c.mean_interval_s - c.min_interval_s) / c.shape
        return c.min_interval_s + float(self._rng.gamma(c.shape, scale))

    def _extend(self, t_s: float) -> None:
        c = self.config
        while self._next_s <= t_s:
            duration = float(self._rng.uniform(c.min_duration_s, c.max_duration_s))
            self._blinks.append(Blink(self._next_s, duration))
            self._starts.append(self._next_s)
            self._next_s += self._interval()

    def blinks_until(self, t_s: float) -> list[Blink]:
        """Every blink that starts at or before ``t_s`` (deterministic for a seed)."""
        self._extend(t_s)
        return [b for b in self._blinks if b.start_s <= t_s]

    def closure(self, t_s: float) -> float:
        """Lid closure of the blink process alone at ``t_s`` (0 open .. amplitude closed)."""
        self._extend(t_s)
        i = bisect.bisect_right(self._starts, t_s) - 1
        if i < 0:
            return 0.0
        blink = self._blinks[i]
        u = (t_s - blink.start_s) / blink.duration_s
        if u >= 1.0:
            return 0.0
        share = self.config.close_share
        shape = min_jerk(u / share) if u < share else 1.0 - min_jerk((u - share) / (1.0 - share))
        return self.config.amplitude * shape

    def suppressed(self, below: Mapping[str, float]) -> bool:
        at, get = self.config.suppress_at, below.get
        for au in LID_AUS[self.face_type]:  # (a loop, not `any` over a generator: every frame)
            if get(au, 0.0) >= at:
                return True
        return False

    def sample(self, t_s: float, below: Mapping[str, float]) -> dict[str, float]:
        if self.suppressed(below):
            return {}
        value = self.closure(t_s)
        return {self.au: value} if value > 0.0 else {}
