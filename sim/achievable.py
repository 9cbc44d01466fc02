"""The achievable face: what the servos make of an AU pose, posed by the twin.

The muscle model's *target* face is a wish; the servos get its actuator targets clamped into their
calibrated ranges, turned into goal ticks and passed (or clipped) by the twin gate. `AchievableFace`
runs that chain without a bus (as the pipeline does) and poses the head from the gated goals through the
calibration inverse and ``FaceModel.pose_from_targets``, so previews and reports show what the head
would really do. Without a calibration file yet, the profile's actuator ranges stand in for the servo
limits (no gate: ``calibrated`` is False and ``note`` says so).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from servoface.sim.rig import HeadPose

SETTLE_FRAMES = 200  # a still is the command the gate settles on, walking from neutral at its rate caps


@dataclass(frozen=True)
class Achieved:
    """One achievable frame: the twin's pose of the gated command and how it came about."""

    pose: HeadPose
    targets: dict[str, float]  # role -> deg / mm the twin sees for the gated goals
    wanted: dict[str, float]  # role -> deg / mm the muscle model asked for
    goals_tick: dict[int, int] = field(default_factory=dict)
    verdict: str = "accept"  # accept / clip / reject (of the last gate check), "ranges" without a gate
    reasons: tuple[str, ...] = ()


def _load_calibration(head: Any, calibration: Any) -> Any:
    if calibration is not None and not isinstance(calibration, str | Path):
        return calibration
    from servoface.calibration import load_calibration

    path = calibration if calibration is not None else getattr(head, "calibration_path", None)
    if path is None or not Path(path).is_file():
        return None
    return load_calibration(path)


class AchievableFace:
    """AU poses -> the face the servos would make (see the module docstring).

    ``calibration``: a loaded calibration, a path, or None for the head's own file (absent: ranges only).
    ``frame_period_s``: the gate's frame period (rate caps scale with it). Calibration errors (a file
    that does not match the head) propagate: they are the user's to fix, not to preview around.
    """

    def __init__(
        self,
        head: Any,
        calibration: Any = None,
        *,
        frame_period_s: float = 0.02,
        model: Any = None,
        gate: Any = None,
    ) -> None:
        from servoface.sim.render.twin import face_model

        self.head = head
        self.model = model if model is not None else face_model(head)
        self.calibration = _load_calibration(head, calibration)
        self.calibrated = self.calibration is not None
        self.gate = gate
        if self.calibration is not None and self.gate is None:
            from servoface.sim.gate import TwinGate

            self.gate = TwinGate(head, self.calibration, frame_period_s, face_model=self.model)
        self.note = (
            ""
            if self.calibrated
            else f"head {head.name!r} has no calibration file yet: the servo limits shown are the profile's "
            "actuator ranges (no twin gate); run `servoface calibrate --head ...` for the real ones"
        )
        roles = [a.role for a in head.actuators]
        if self.calibration is not None:
            servos = [self.calibration[r] for r in roles]
            self._lo = np.array([s.min_target for s in servos])
            self._hi = np.array([s.max_target for s in servos])
        else:
            self._lo = np.array([a.lower_deg if a.kind == "joint" else a.lower_mm for a in head.actuators])
            self._hi = np.array([a.upper_deg if a.kind == "joint" else a.upper_mm for a in head.actuators])
        self._roles = roles
        self._last: dict[int, int] | None = None

    # ------------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Start the next `step` from the neutral command at rest."""
        self._last = None
        if self.gate is not None:
            self.gate.reset()

    def _clamped(self, wanted: Mapping[str, float]) -> dict[str, float]:
        values = np.array([float(wanted[r]) for r in self._roles])
        return dict(zip(self._roles, np.clip(values, self._lo, self._hi).tolist(), strict=True))

    def step(self, aus: Mapping[str, float]) -> Achieved:
        """One frame after the previous `step` (a clip): the gate sees the rate from the last command."""
        wanted = dict(self.model.solve(aus).actuator_targets)
        targets = self._clamped(wanted)
        if self.calibration is None or self.gate is None:
            return Achieved(self.model.pose_from_targets(targets), targets, wanted, verdict="ranges")
        requested = self.calibration.targets_to_goals(targets)
        last = self._last if self._last is not None else self.gate.neutral_goals()
        verdict = self.gate.check(requested, last)
        return self._achieved(verdict, wanted)

    def still(self, aus: Mapping[str, float]) -> Achieved:
        """The command the gate settles on for holding ``aus`` from neutral (an apex still)."""
        self.reset()
        wanted = dict(self.model.solve(aus).actuator_targets)
        targets = self._clamped(wanted)
        if self.calibration is None or self.gate is None:
            return Achieved(self.model.pose_from_targets(targets), targets, wanted, verdict="ranges")
        requested = self.calibration.targets_to_goals(targets)
        last = self.gate.neutral_goals()
        verdict = None
        for _ in range(SETTLE_FRAMES):
            verdict = self.gate.check(requested, last)
            if verdict.kind == "accept" or verdict.goals_tick == last:
                break
            last = dict(verdict.goals_tick)
        if verdict is None:  # pragma: no cover - SETTLE_FRAMES > 0
            raise RuntimeError("no gate check ran")
        return self._achieved(verdict, wanted)

    def _achieved(self, verdict: Any, wanted: dict[str, float]) -> Achieved:
        goals = {int(k): int(v) for k, v in verdict.goals_tick.items()}
        self._last = goals
        targets = self.calibration.goals_to_targets(goals, clip=True)
        pose = self.model.pose_from_targets(targets)
        return Achieved(pose, targets, wanted, goals, verdict.kind, tuple(verdict.reasons()))
