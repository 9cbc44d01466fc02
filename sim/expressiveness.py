"""What a head can express: per AU and per expression, the servos' achievable face vs the muscle-model target.

Both faces are posed (skin vertices after skinning, plus the vertices of every rigid part) and compared
point by point: ``max_error_mm`` is the largest distance between the target and the achievable position of
any point, ``shown`` the share of the target's motion the servos reproduce (1 - summed error / summed
motion). An AU the head *cannot show* moves nothing in the achievable face although it is an AU of the
table (or moves nothing at all on this head); each comes with the reason: a row that reaches nothing
here (missing muscles or joints), "no actuator drives joint X", "no actuator reaches muscle X" (skin no
anchor sees), "shared servo R drives J1, J2 by one angle", or what the ranges / the twin gate refused.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
MOVES_MM = 0.5  # a point that moves less than this does not count as showing anything
PART_POINTS = 400  # vertices sampled per rigid part


@dataclass(frozen=True)
class Score:
    """How much of one AU (or expression) a head shows."""

    name: str
    target_motion_mm: float  # the largest motion of any point in the muscle-model target
    achieved_motion_mm: float  # the largest motion of any point in the achievable face
    max_error_mm: float
    mean_error_mm: float  # over the points the target moves
    shown: float  # 0..1
    cannot_show: bool
    reasons: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "target_motion_mm": round(self.target_motion_mm, 2),
            "achieved_motion_mm": round(self.achieved_motion_mm, 2),
            "max_error_mm": round(self.max_error_mm, 2),
            "mean_error_mm": round(self.mean_error_mm, 2),
            "shown": round(self.shown, 3),
            "cannot_show": self.cannot_show,
            "reasons": list(self.reasons),
        }


class FacePoints:
    """Posed comparison points of a head: every skin vertex and up to PART_POINTS vertices per part."""

    def __init__(self, head: Any) -> None:
        self.head = head
        self._parts = []
        for p in head.parts:
            v = np.asarray(p.mesh.vertices, dtype=np.float64)
            step = max(1, len(v) // PART_POINTS)
            self._parts.append((p.name, p.joint, np.c_[v[::step], np.ones(len(v[::step]))]))

    def __call__(self, pose: Any) -> FloatArray:
        from servoface.sim.kinematics import part_transforms, posed_skin_vertices

        chunks = []
        if self.head.has_skin:
            chunks.append(np.asarray(posed_skin_vertices(self.head, pose), dtype=np.float64))
        transforms = part_transforms(self.head, pose.joint_deg)
        for name, _, hom in self._parts:
            m = np.asarray(transforms[name], dtype=np.float64)
            chunks.append((hom @ m.T)[:, :3])
        return np.concatenate(chunks) if chunks else np.zeros((0, 3))


def compare(points: FloatArray, target: FloatArray, achieved: FloatArray) -> tuple[float, float, float, float, float]:
    """(target motion, achieved motion, max error, mean error over moved points, shown) in mm / 0..1."""
    if len(points) == 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    motion = np.linalg.norm(target - points, axis=1)
    got = np.linalg.norm(achieved - points, axis=1)
    error = np.linalg.norm(target - achieved, axis=1)
    moved = motion > MOVES_MM
    total = float(motion[moved].sum())
    shown = 0.0 if total <= 0 else float(np.clip(1.0 - error[moved].sum() / total, 0.0, 1.0))
    mean = float(error[moved].mean()) if moved.any() else 0.0
    return float(motion.max()), float(got.max()), float(error.max()), mean, shown


class Expressiveness:
    """Scores AUs and expressions of one head through an `servoface.sim.achievable.AchievableFace`."""

    def __init__(self, achievable: Any) -> None:
        self.twin = achievable
        self.model = achievable.model
        self.head = achievable.head
        self.points = FacePoints(self.head)
        self.rest = self.points(self.model.solve({}))
        self.driven = {j: a.role for a in self.head.joint_actuators for j in a.joints}
        fit = getattr(self.model, "fit", None)
        unit = np.asarray(getattr(fit, "unit_pull", np.zeros((0, 0))))
        self.reached = set() if unit.size == 0 else {
            name for k, name in enumerate(self.model.field.names) if np.abs(unit[:, k]).max() > 1e-6
        }  # fmt: skip

    def score(self, name: str, aus: Mapping[str, float]) -> Score:
        solution = self.model.solve_detailed(aus)
        target = self.points(solution.pose)
        got = self.twin.still(aus)
        achieved = self.points(got.pose)
        t_move, a_move, max_err, mean_err, shown = compare(self.rest, target, achieved)
        cannot = t_move < MOVES_MM or a_move < MOVES_MM
        reasons = self._reasons(aus, solution, got) if (cannot or shown < 0.9) else []
        if not reasons and t_move >= MOVES_MM and shown < 0.9:
            reasons = [f"the skin the servos' anchor pulls make misses the muscle face by up to {max_err:.1f} mm"]
        return Score(name, t_move, a_move, max_err, mean_err, shown, cannot, tuple(reasons))

    def _reasons(self, aus: Mapping[str, float], solution: Any, got: Any) -> list[str]:
        out: list[str] = []
        numbers = set()
        from servoface.sim.au.mapping import canonical_au_name

        for au in aus:
            numbers.add(canonical_au_name(au)[0])
        unreachable = self.model.unreachable
        for n in sorted(numbers):
            if n in unreachable:
                out.append(f"AU{n} reaches nothing on this head: {unreachable[n]}")
        neutral = self.model.solve({}).joint_deg
        _, raw = self.model.mapping.evaluate(aus)
        for joint, delta in zip(self.head.joints, raw.tolist(), strict=True):
            asked = joint.neutral_deg + delta
            if abs(delta) > 0.1 and not joint.lower_deg - 1e-6 <= asked <= joint.upper_deg + 1e-6:
                out.append(
                    f"joint {joint.name} is asked for {asked:.1f} deg, beyond its limits "
                    f"[{joint.lower_deg:g}, {joint.upper_deg:g}]"
                )
        moved = {j for j, v in solution.pose.joint_deg.items() if abs(v - neutral[j]) > 0.1}
        loose = sorted(j for j in moved if j not in self.driven)
        if loose:
            out.append(f"no actuator drives joint{'s' if len(loose) > 1 else ''} {', '.join(loose)}")
        for act in self.head.joint_actuators:
            if len(act.joints) > 1:
                angles = [solution.pose.joint_deg[j] for j in act.joints]
                if max(angles) - min(angles) > 0.5:
                    out.append(
                        f"shared servo {act.role!r} drives {', '.join(act.joints)} by one angle "
                        f"(asked for {', '.join(f'{a:.1f}' for a in angles)} deg)"
                    )
        unseen = sorted(m for m, c in solution.contractions.items() if abs(c) > 1e-3 and m not in self.reached)
        if unseen:
            out.append(f"no actuator reaches muscle{'s' if len(unseen) > 1 else ''} {', '.join(unseen)}")
        short = [
            f"{r} {got.targets[r]:.1f} of {got.wanted[r]:.1f}"
            for r in got.targets
            if abs(got.targets[r] - got.wanted[r]) > 0.25
        ]
        if short:
            out.append(f"servo ranges or the twin gate hold back: {', '.join(short)} (deg/mm)")
        if got.verdict not in ("accept", "ranges") and got.reasons:
            # the rate caps fire on every walk from neutral; the state check that stopped it says why
            state = [r for r in got.reasons if not r.startswith(("[speed]", "[accel]", "[hold]"))]
            out.append(f"twin gate {got.verdict}: {(state or list(got.reasons))[0]}")
        return out

    def au_scores(self) -> list[Score]:
        """Every AU of the head's table at full intensity (a signed AU also at -1, named ``AU5-``), plus one
        side alone of each sided AU (``AU12L``) when that side cannot move alone."""
        table = self.model.mapping.table
        out = []
        for number in sorted(table.entries):
            entry = table.entries[number]
            lo, hi = entry.range
            if hi > 0:
                out.append(self.score(f"AU{number}", {f"AU{number}": hi}))
                if entry.sided and self._splits_a_shared_servo({f"AU{number}L": hi}):
                    out.append(self.score(f"AU{number}L", {f"AU{number}L": hi}))
            if lo < 0:
                out.append(self.score(f"AU{number}-", {f"AU{number}": lo}))
        return out

    def _splits_a_shared_servo(self, aus: Mapping[str, float]) -> bool:
        joint_deg = self.model.solve(aus).joint_deg
        for act in self.head.joint_actuators:
            angles = [joint_deg[j] for j in act.joints]
            if len(angles) > 1 and max(angles) - min(angles) > 0.5:
                return True
        return False

    def expression_scores(self, library: Mapping[str, Any]) -> list[Score]:
        from servoface.sim.render.clips import apex_aus

        return [self.score(name, apex_aus(expr)) for name, expr in library.items()]


def cannot_show(scores: list[Score]) -> list[Score]:
    return [s for s in scores if s.cannot_show]
