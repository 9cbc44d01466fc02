"""The twin's pose from servo goals: calibration inverse -> actuator targets -> joint angles and pulls.

Works on (k, n_servos) tick arrays in the calibration's column order, so one frame and a batch of
candidate commands share the same code.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.fk import JointTree

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class TwinPoser:
    """Maps goal ticks to joint angles (deg, JointTree order) and anchor pulls (mm from neutral)."""

    def __init__(self, head: Any, calibration: Any, tree: JointTree) -> None:
        self.calibration = calibration
        self.tree = tree
        self.roles: tuple[str, ...] = tuple(calibration.roles)
        self.ids: tuple[int, ...] = tuple(int(i) for i in calibration.ids)
        actuators = {a.role: a for a in head.actuators}
        missing = [r for r in self.roles if r not in actuators]
        extra = [r for r in actuators if r not in self.roles]
        if missing or extra:
            raise GateConfigError(
                f"calibration '{getattr(calibration, 'head', '?')}' and head '{head.name}' disagree on "
                f"roles: "
                f"not in head {missing}, not calibrated {extra}"
            )
        head_ids = {a.role: a.servo.id for a in head.actuators}
        wrong = [(r, i, head_ids[r]) for r, i in zip(self.roles, self.ids, strict=True) if head_ids[r] != i]
        if wrong:
            raise GateConfigError(f"calibration ids differ from the head profile (role, cal id, head id): {wrong}")
        self.actuators = tuple(actuators[r] for r in self.roles)
        # joint columns: servo column -> joints it drives
        jc: list[int] = []
        jj: list[int] = []
        for c, a in enumerate(self.actuators):
            if a.kind == "joint":
                for name in a.joints:
                    jc.append(c)
                    jj.append(tree.index[name])
        self._joint_col = np.array(jc, dtype=np.int64)
        self._joint_idx = np.array(jj, dtype=np.int64)
        self.anchor_cols = np.array([c for c, a in enumerate(self.actuators) if a.kind == "anchor"], dtype=np.int64)
        self.anchor_roles = tuple(self.roles[c] for c in self.anchor_cols)
        self.anchor_neutral_mm = np.array([self.actuators[c].neutral_mm for c in self.anchor_cols], dtype=np.float64)
        servos = calibration.servos
        self.min_tick = np.array([s.min_tick for s in servos], dtype=np.int64)
        self.max_tick = np.array([s.max_tick for s in servos], dtype=np.int64)
        self.neutral_tick = np.array([s.neutral_tick for s in servos], dtype=np.int64)
        self.models = [s.model for s in servos]
        self.target_lower = np.array([_lower(a) for a in self.actuators])
        self.target_upper = np.array([_upper(a) for a in self.actuators])
        self.target_neutral = np.array([_neutral(a) for a in self.actuators])

        self._build_lut(servos)

    def _build_lut(self, servos: Any) -> None:
        """Targets of every integer tick of every uncoupled servo, so inverting the calibration per frame
        is one gather (exact: the curve evaluated at the same integer ticks)."""
        span = self.max_tick - self.min_tick + 1
        self._lut_offset = np.r_[0, np.cumsum(span)[:-1]].astype(np.int64)
        grid = np.concatenate([np.arange(lo, hi + 1) for lo, hi in zip(self.min_tick, self.max_tick, strict=True)])
        cols = np.repeat(np.arange(len(span)), span)
        table = np.tile(self.neutral_tick, (len(grid), 1))
        table[np.arange(len(grid)), cols] = grid
        full = np.asarray(self.calibration.goals_to_targets_array(table, clip=True), dtype=np.float64)
        self._lut = full[np.arange(len(grid)), cols]
        self._coupled = np.array([s.coupling is not None for s in servos], dtype=bool)
        self._any_coupled = bool(self._coupled.any())
        self._lut_shift = self._lut_offset - self.min_tick

    def targets(self, ticks: IntArray) -> FloatArray:
        """(k, n) actuator targets (deg / mm) for (k, n) ticks (clipped into the tick limits)."""
        t = np.atleast_2d(ticks)
        k = np.clip(t, self.min_tick, self.max_tick) - self.min_tick + self._lut_offset
        out = self._lut[k]
        if self._coupled.any():
            full = self.calibration.goals_to_targets_array(t, clip=True)
            out[:, self._coupled] = np.asarray(full, dtype=np.float64)[:, self._coupled]
        return np.asarray(out, dtype=np.float64)

    def pose_one(self, ticks: IntArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(targets (n,), joint angles (J,), pulls (a,)) of one (n,) command: `targets`, `joint_angles` and
        `pulls` of a batch of one, the same numbers (the same gather, assignments and clip) on flat arrays
        with fewer numpy calls; a head with coupled servos takes the batch path."""
        if self._any_coupled:
            targets = self.targets(ticks[None, :])
            return targets[0], self.joint_angles(targets)[0], self.pulls(targets)[0]
        k = np.clip(ticks, self.min_tick, self.max_tick) + self._lut_shift  # (k - min) + offset: exact integers
        targets = self._lut.take(k)
        q = self.tree.neutral_deg.copy()
        q[self._joint_idx] = targets.take(self._joint_col)
        return targets, np.clip(q, self.tree.lower_deg, self.tree.upper_deg), targets.take(self.anchor_cols)

    def columns_driving(self, joints: list[int]) -> NDArray[np.bool_]:
        """(n,) mask of the servo columns whose targets set any of ``joints`` (JointTree indices)."""
        mask = np.zeros(len(self.roles), dtype=bool)
        mask[self._joint_col[np.isin(self._joint_idx, np.asarray(joints, dtype=np.int64))]] = True
        return mask

    @property
    def coupled(self) -> bool:
        """Some servo's target depends on other servos' ticks (a calibration coupling)."""
        return self._any_coupled

    def joint_angles(self, targets: FloatArray) -> FloatArray:
        """(k, J) joint angles: driven joints from their servo's target, the rest at neutral, all clamped to
        the joint limits (the rig's hard stops, as in `servoface.sim.kinematics`)."""
        q = np.broadcast_to(self.tree.neutral_deg, (targets.shape[0], len(self.tree.names))).copy()
        q[:, self._joint_idx] = targets[:, self._joint_col]
        return np.clip(q, self.tree.lower_deg, self.tree.upper_deg)

    def pulls(self, targets: FloatArray) -> FloatArray:
        """(k, n_anchors) anchor pulls (mm along each line, absolute like the actuator targets)."""
        return targets[:, self.anchor_cols]


def _lower(a: Any) -> float:
    return float(a.lower_deg if a.kind == "joint" else a.lower_mm)


def _upper(a: Any) -> float:
    return float(a.upper_deg if a.kind == "joint" else a.upper_mm)


def _neutral(a: Any) -> float:
    return float(a.neutral_deg if a.kind == "joint" else a.neutral_mm)
