"""Idle motion: low-amplitude smooth noise on head and eyes so a resting face looks alive.

Each channel (head yaw, pitch, roll; eye yaw, pitch) is a uniform cubic B-spline through seeded random
control values in [-1, 1] spaced ``period_s`` apart: C2-smooth (no velocity or acceleration steps for the
servos) and bounded by the control values, so |output| <= amplitude. Amplitudes are AU units (fractions of
the joint limits of :class:`GazeConfig`): defaults 0.03 head (about 1.8 deg of yaw), 0.04 eyes.

"When nothing plays": give ``busy`` (e.g. ``timeline.is_playing``); the idle gain is the share of the last
``fade_s`` seconds that was not busy (sampled at 8 points), so idle fades out while a clip plays and back
in afterwards. Pure function of time.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from servoface.controller.alive.gaze import GazeConfig, gaze_config_for
from servoface.controller.alive.gaze_layer import angles_to_aus
from servoface.controller.errors import TimelineError
from servoface.sim.rig import FaceType

CHANNELS = ("head_yaw", "head_pitch", "head_roll", "eye_yaw", "eye_pitch")


@dataclass(frozen=True)
class IdleConfig:
    head_amplitude: float = 0.03
    eye_amplitude: float = 0.04
    head_period_s: float = 2.5
    eye_period_s: float = 1.3
    fade_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("head_amplitude", "eye_amplitude"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0.0 <= value <= 0.3):
                raise TimelineError(f"idle.{name}: expected a small AU amplitude 0..0.3, got {value!r}")
        for name in ("head_period_s", "eye_period_s", "fade_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise TimelineError(f"idle.{name}: expected a duration > 0 s, got {value!r}")


def _bspline(c0: float, c1: float, c2: float, c3: float, u: float) -> float:
    u2, u3 = u * u, u * u * u
    return (c0 * (1 - u) ** 3 + c1 * (3 * u3 - 6 * u2 + 4) + c2 * (-3 * u3 + 3 * u2 + 3 * u + 1) + c3 * u3) / 6.0


@dataclass
class IdleLayer:
    face_type: FaceType
    seed: int = 0
    config: IdleConfig = field(default_factory=IdleConfig)
    gaze: GazeConfig | None = None  # AU full scales; None = gaze_config_for(face_type)
    busy: Callable[[float], bool] | None = None
    uses_below: ClassVar[bool] = False

    def __post_init__(self) -> None:
        self._scale: GazeConfig = self.gaze if self.gaze is not None else gaze_config_for(self.face_type)
        self._rng = np.random.default_rng(self.seed)
        self._knots: dict[str, list[float]] = {c: [] for c in CHANNELS}

    def _knot(self, channel: str, k: int) -> float:
        knots = self._knots[channel]
        while len(knots) <= k:  # grow every channel in lockstep so values do not depend on query order
            for c in CHANNELS:
                self._knots[c].append(float(self._rng.uniform(-1.0, 1.0)))
        return knots[k]

    def channel(self, name: str, t_s: float) -> float:
        """Noise in [-1, 1] for one channel at ``t_s`` (t < 0 is treated as 0)."""
        period = self.config.head_period_s if name.startswith("head") else self.config.eye_period_s
        x = max(0.0, t_s) / period
        k = int(math.floor(x))
        knots = self._knots[name]
        if len(knots) <= k + 3:
            self._knot(name, k + 3)  # (every channel grows in lockstep: the same draws as knot by knot)
        return _bspline(knots[k], knots[k + 1], knots[k + 2], knots[k + 3], x - k)

    def gain(self, t_s: float) -> float:
        if self.busy is None:
            return 1.0
        n, busy, fade_s = 8, self.busy, self.config.fade_s
        quiet = 0
        for j in range(n):  # (a loop, not `sum` over a generator: every frame)
            if not busy(t_s - fade_s * j / (n - 1)):
                quiet += 1
        return quiet / n

    def sample(self, t_s: float, below: Mapping[str, float] | None = None) -> dict[str, float]:
        g = self.gain(t_s)
        if g <= 0.0:
            return {}
        ha, ea = g * self.config.head_amplitude, g * self.config.eye_amplitude
        cfg = self._scale
        return angles_to_aus(
            self.face_type,
            cfg,
            head_yaw_deg=ha * self.channel("head_yaw", t_s) * cfg.neck_limit_yaw_deg,
            head_pitch_deg=ha * self.channel("head_pitch", t_s) * cfg.neck_limit_pitch_deg,
            eye_yaw_deg=ea * self.channel("eye_yaw", t_s) * cfg.eye_limit_yaw_deg,
            eye_pitch_deg=ea * self.channel("eye_pitch", t_s) * cfg.eye_limit_pitch_deg,
            head_roll_deg=ha * self.channel("head_roll", t_s) * cfg.neck_limit_roll_deg,
        )
