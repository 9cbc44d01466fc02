"""Any mouth clip within the jaw's thermal budget: a script's edited mouth keys (the ``speech`` track played
with its sound file) go through the same account as synthesised speech (:mod:`.jaw_budget`).

The clip's jaw opening is read from its jaw AUs (the ``open`` row of the face's speech recipe: human AU26,
dog AU7 / 0.8) sampled at :data:`RATE_HZ`; the budget scales that opening down exactly as it scales a
plan's; the clip then plays with its jaw AUs multiplied by the budget's scale at that time (the lips, the
other mouth AUs and every key's timing untouched)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.jaw_budget import BudgetReport, JawBudget, JawThermal
from servoface.controller.speech.visemes import RECIPES

RATE_HZ = 100.0  # as the lip-sync plans (plan.PLAN_RATE_HZ)


def jaw_gains(face_type: str) -> dict[str, float]:
    """The jaw AUs of a face type and how much of each a full opening is."""
    return dict(RECIPES[face_type]["open"])


def opening_of(pose: Mapping[str, float], gains: Mapping[str, float]) -> float:
    """How far ``pose`` opens the jaw (0..1)."""
    most = max((float(pose.get(au, 0.0)) / g for au, g in gains.items() if g > 0), default=0.0)
    return min(1.0, max(0.0, most))


@dataclass(frozen=True)
class JawScaledClip:
    """``inner`` with its jaw AUs scaled by ``scale`` (at ``times_s``, linear between)."""

    inner: Any
    times_s: NDArray[np.float64]
    scale: NDArray[np.float64]
    gains: Mapping[str, float]

    @property
    def name(self) -> str:
        return str(getattr(self.inner, "name", "speech"))

    @property
    def holds(self) -> bool:
        return bool(getattr(self.inner, "holds", False))

    @property
    def duration_s(self) -> float:
        return float(self.inner.duration_s)

    def sample(self, t_s: float, from_pose: Mapping[str, float]) -> dict[str, float]:
        pose = dict(self.inner.sample(t_s, from_pose))
        k = float(np.interp(t_s, self.times_s, self.scale)) if len(self.times_s) else 1.0
        for au in self.gains:
            if au in pose:
                pose[au] = pose[au] * k
        return pose

    def end_pose(self, from_pose: Mapping[str, float]) -> dict[str, float]:
        return dict(self.inner.end_pose(from_pose))

    def targets(self) -> Iterator[tuple[str, float]]:
        return iter(self.inner.targets())


def budget_clip(
    clip: Any, face_type: str, start_s: float, budget: JawBudget, jaw: JawThermal | None
) -> tuple[JawScaledClip, BudgetReport]:
    """``clip`` (starting at ``start_s`` monotonic) with its jaw within ``budget`` (the account runs on)."""
    gains = jaw_gains(face_type)
    duration = max(0.0, float(clip.duration_s))
    times = np.arange(0.0, duration + 1e-9, 1.0 / RATE_HZ)
    opening = np.array([opening_of(clip.sample(float(t), {}), gains) for t in times.tolist()])
    kept, report = budget.apply_opening(times, opening, start_s, jaw)
    scale = np.where(opening > 1e-9, kept / np.maximum(opening, 1e-9), report.jaw_gain)
    return JawScaledClip(clip, times, np.clip(scale, 0.0, 1.0), gains), report
