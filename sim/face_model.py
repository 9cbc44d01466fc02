"""The face model: AUs -> a posed head (joint angles + skin offsets) -> actuator targets, and back.

``FaceModel(head).solve(aus)`` validates the AUs, maps them through the head's AU table to muscle
contractions and joint angles (sum of signed contributions, then clamp: contractions to the table's range,
joints to their limits), deforms the rest skin by the precomputed Waters-style muscle fields
(``servoface.sim.muscles.field``), and reads the actuator targets off the result:

- joint actuator  -> the mean angle of its joints (deg), clamped to the actuator's range;
- anchor actuator -> the skin offset of its anchor vertex projected on its line of action (mm), clamped.

``pose_from_targets(targets)`` is the twin's inverse: joints straight from the joint targets, skin from the
anchor pulls by a bounded least-squares fit of muscle contractions plus exact per-anchor bumps
(``servoface.sim.muscles.fit``). Everything heavy is precomputed in the constructor: one ``solve`` is two small
matrix products, one sparse matrix-vector product and a few dictionary builds.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.au.direct import DirectMapping, DirectTable, load_direct_table
from servoface.sim.au.mapping import AUMapping, canonical_au_name, check_au
from servoface.sim.au.table import AUTable, au_table_path, load_au_table, with_vocabulary
from servoface.sim.errors import HeadProfileError, PoseError, UnknownActionUnitError
from servoface.sim.muscles import (
    EyelidMuscle,
    LinearMuscle,
    Muscle,
    SheetMuscle,
    SphincterMuscle,
    muscle_from_mapping,
)
from servoface.sim.muscles.field import MuscleField
from servoface.sim.muscles.fit import AnchorFit
from servoface.sim.rig import AnchorActuator, HeadPose, JointActuator

FloatArray = NDArray[np.float64]


def as_model_muscle(muscle: Any) -> Muscle:
    """A muscle of ``servoface.sim.muscles`` from any record with the same fields (e.g. ``sim.rig``'s)."""
    if isinstance(muscle, LinearMuscle | SheetMuscle | SphincterMuscle | EyelidMuscle):
        return muscle
    name = getattr(muscle, "name", None)
    if not dataclasses.is_dataclass(muscle) or isinstance(muscle, type) or not isinstance(name, str):
        raise HeadProfileError(f"muscle {muscle!r}: expected a muscle dataclass with name and type fields")
    data = {k: v for k, v in dataclasses.asdict(muscle).items() if v is not None and k != "name"}
    data = {k: list(v) if isinstance(v, tuple) else v for k, v in data.items()}
    return muscle_from_mapping(name, data, f"muscles.{name}")


@dataclasses.dataclass(frozen=True)
class FaceSolution:
    """A solved frame with the muscle state behind it (for inspection and tests)."""

    pose: HeadPose
    contractions: dict[str, float]


class FaceModel:
    """AUs -> HeadPose (with actuator targets) for one head, and actuator targets -> HeadPose (the twin).

    ``au_table``: a table, a file path, or None for the head's ``au_table_path`` (else the built-in table
    of its face type). A head's own table is completed with empty rows for the AUs of its face type it
    leaves out (they validate and move nothing). The table is applied to what the head has: muscles and
    joints it lacks are skipped (``self.mapping.missing``, per AU in ``self.mapping.notes``) and AUs that
    reach nothing are listed in ``self.unreachable`` with the reason; ``allow_missing=False`` makes a
    missing name a HeadProfileError instead. ``direct``: a direct AU -> actuator-target table
    (`servoface.sim.au.direct`; default the head's ``au_direct_path``): the AUs it lists are driven
    from it, the rest through the muscles. Skin, muscles, anchors and joints are all optional.
    """

    def __init__(
        self,
        head: Any,
        au_table: AUTable | str | Path | None = None,
        *,
        allow_missing: bool = True,
        direct: DirectTable | str | Path | None = None,
    ) -> None:
        self.head = head
        rest = np.asarray(head.skin.vertices_mm, dtype=np.float64)
        self.n_vertices = int(rest.shape[0])
        muscles = [as_model_muscle(m) for m in _values(head.muscles)]
        faces = getattr(head.skin, "faces", None)
        self.field = MuscleField(muscles, rest, None if faces is None else np.asarray(faces))
        if isinstance(au_table, AUTable):
            table = au_table
        else:
            table = load_au_table(au_table or getattr(head, "au_table_path", None) or head.face_type)
        if table.face_type != head.face_type:
            raise HeadProfileError(
                f"{table.path}: face_type {table.face_type!r} does not match head {head.name!r} ({head.face_type!r})"
            )
        if table.path != au_table_path(head.face_type):
            table = with_vocabulary(table, load_au_table(head.face_type))
        joints = _values(head.joints)
        actuators = _values(head.actuators)
        self.joint_names: tuple[str, ...] = tuple(j.name for j in joints)
        direct_table = direct if isinstance(direct, DirectTable) else None
        direct_path = direct if isinstance(direct, str | Path) else getattr(head, "au_direct_path", None)
        if direct_table is None and direct_path is not None:
            direct_table = load_direct_table(direct_path)
        if direct_table is not None and direct_table.face_type != head.face_type:
            raise HeadProfileError(
                f"{direct_table.path}: face_type {direct_table.face_type!r} does not match head "
                f"{head.name!r} ({head.face_type!r})"
            )
        skip = frozenset(direct_table.rows) if direct_table is not None else frozenset()
        self.mapping = AUMapping(table, self.field.names, self.joint_names, allow_missing, skip)
        self.direct: DirectMapping | None = None
        if direct_table is not None:
            self.direct = DirectMapping(
                direct_table,
                self.mapping.channels,
                {n: e.sided for n, e in table.entries.items()},
                [a.role for a in actuators],
            )
        self._neutral = np.array([j.neutral_deg for j in joints], dtype=np.float64)
        self._lower = np.array([j.lower_deg for j in joints], dtype=np.float64)
        self._upper = np.array([j.upper_deg for j in joints], dtype=np.float64)
        j_index = {n: i for i, n in enumerate(self.joint_names)}
        self.joint_actuators = [a for a in actuators if isinstance(a, JointActuator)]
        self.anchor_actuators = [a for a in actuators if isinstance(a, AnchorActuator)]
        for act in self.joint_actuators:
            missing = [j for j in act.joints if j not in j_index]
            if missing:
                raise HeadProfileError(f"actuators.{act.role}.joints: unknown joint(s) {missing}")
        for anchor in self.anchor_actuators:
            if not 0 <= anchor.vertex < self.n_vertices:
                raise HeadProfileError(
                    f"actuators.{anchor.role}.vertex: expected a skin vertex 0..{self.n_vertices - 1}, "
                    f"got {anchor.vertex}"
                )
        self._joint_cols = [np.array([j_index[j] for j in a.joints]) for a in self.joint_actuators]
        self._anchor_vertex = np.array([a.vertex for a in self.anchor_actuators], dtype=np.int64)
        self._anchors_kept: tuple[tuple[bytes, bytes], list[float]] | None = None  # see actuator_targets
        lines = np.array([a.line for a in self.anchor_actuators], dtype=np.float64).reshape(-1, 3)
        norms = np.linalg.norm(lines, axis=1)
        self._anchor_line = lines / np.where(norms > 0, norms, 1.0)[:, None]
        unit = self.field.unit_displacements(self._anchor_vertex)  # (A, 3, M)
        unit_pull = np.einsum("ak,akm->am", self._anchor_line, unit)
        self.fit = AnchorFit(
            unit_pull,
            table.contraction,
            rest,
            self._anchor_vertex,
            self._anchor_line,
            [a.radius_mm for a in self.anchor_actuators],
            slit=self.field.slit,
            near=self.field.near,
        )
        self.roles: tuple[str, ...] = tuple(a.role for a in actuators)
        self._direct_setup()

    def _direct_setup(self) -> None:
        """Index maps for the direct table's rows (joint actuators, anchor actuators) and the AUs it reaches."""
        order = {a.role: i for i, a in enumerate(self.joint_actuators)}
        anchors = {a.role: i for i, a in enumerate(self.anchor_actuators)}
        self._direct_joint: list[tuple[int, int]] = []  # (direct row, joint actuator index)
        self._direct_anchor: list[tuple[int, int]] = []
        if self.direct is not None:
            for row, role in enumerate(self.direct.roles):
                if role in order:
                    self._direct_joint.append((row, order[role]))
                elif role in anchors:
                    self._direct_anchor.append((row, anchors[role]))

    @property
    def unreachable(self) -> dict[int, str]:
        """AU number -> why its row moves nothing on this head (missing muscles/joints, no direct target)."""
        out = dict(self.mapping.unreachable)
        if self.direct is not None:
            k = len(self.mapping.channels)
            used = np.abs(self.direct.matrix).sum(axis=0) > 0
            for number in self.direct.numbers:
                cols = [i for i, (n, _) in enumerate(self.mapping.channels) if n == number]
                if not (used[cols].any() or used[[c + k for c in cols]].any()):
                    notes = self.direct.notes.get(number) or ["its direct table row has no targets"]
                    out[number] = "direct table: " + "; ".join(notes)
        return dict(sorted(out.items()))

    # --- the AU vocabulary of this head -----------------------------------------------------------------

    @property
    def au_names(self) -> frozenset[str]:
        """Every AU name ``solve`` accepts (AU12, AU12L, AU12R, ...)."""
        return self.mapping.table.names()

    def au_range(self, name: str) -> tuple[float, float]:
        """The allowed intensity interval of one AU name (UnknownActionUnitError if unknown)."""
        table = self.mapping.table
        number, side = canonical_au_name(name)
        entry = table.entries.get(number)
        if entry is None or (side and not entry.sided):
            check_au(table, name, 0.0)  # raises the typed error naming the AU
            raise UnknownActionUnitError(f"{name}: not in the {table.face_type} AU table")  # pragma: no cover
        return entry.range

    # --- forward: AUs -> pose ---------------------------------------------------------------------------

    def solve(self, aus: Mapping[str, float]) -> HeadPose:
        """The posed head for one AU frame (validated first; a bad AU raises and nothing is computed)."""
        return self.solve_detailed(aus).pose

    def solve_detailed(self, aus: Mapping[str, float]) -> FaceSolution:
        split = self.mapping.split(aus)
        contractions, joint_delta = self.mapping.evaluate_split(split)
        joint = np.clip(self._neutral + joint_delta, self._lower, self._upper)
        joint_deg = dict(zip(self.joint_names, joint.tolist(), strict=True))
        offsets = self.field.offsets(contractions, joint_deg if self.field.eyelids else None)
        targets = self._targets(joint, offsets[self._anchor_vertex])
        if self.direct is not None and split.any():
            joint_deg, offsets = self._apply_direct(self.direct.deltas(split), joint, joint_deg, offsets, targets)
        pose = HeadPose(joint_deg, offsets, targets)
        return FaceSolution(pose, dict(zip(self.field.names, contractions.tolist(), strict=True)))

    def _apply_direct(
        self,
        deltas: FloatArray,
        joint: FloatArray,
        joint_deg: dict[str, float],
        offsets: FloatArray,
        targets: dict[str, float],
    ) -> tuple[dict[str, float], FloatArray]:
        """Add the direct table's target offsets (updates ``targets``); the pose follows: joint actuators
        set their joints, anchor pulls move the skin by the twin's per-anchor bumps."""
        changed = False
        for row, i in self._direct_joint:
            if deltas[row] == 0.0:
                continue
            act = self.joint_actuators[i]
            value = min(max(targets[act.role] + float(deltas[row]), act.lower_deg), act.upper_deg)
            targets[act.role] = value
            joint[self._joint_cols[i]] = value
            changed = True
        if changed:
            joint = np.clip(joint, self._lower, self._upper)
            joint_deg = dict(zip(self.joint_names, joint.tolist(), strict=True))
        residual = np.zeros(len(self.anchor_actuators))
        for row, i in self._direct_anchor:
            if deltas[row] == 0.0:
                continue
            anchor = self.anchor_actuators[i]
            value = min(max(targets[anchor.role] + float(deltas[row]), anchor.lower_mm), anchor.upper_mm)
            residual[i] = value - targets[anchor.role]
            targets[anchor.role] = value
        if residual.any():
            offsets = offsets + self.fit.bumps(residual)
        return joint_deg, offsets

    def actuator_targets(self, aus: Mapping[str, float]) -> dict[str, float]:
        """``solve(aus).actuator_targets`` (validated the same way) without posing the skin: only the anchor
        vertices' offsets are computed (`MuscleField.offsets_at`), the rest of the arithmetic is `solve`'s.
        The anchors' pulls are kept for the last contractions (and joints, with eyelids): a frame that moves
        only joints (gaze, idle, a blink on a lid joint) does not evaluate the skin again. A head with a
        direct table falls back to `solve` when a frame uses it."""
        split = self.mapping.split(aus)
        if self.direct is not None and split.any():
            return dict(self.solve_detailed(aus).pose.actuator_targets)
        contractions, joint_delta = self.mapping.evaluate_split(split)
        joint = np.minimum(np.maximum(self._neutral + joint_delta, self._lower), self._upper)  # (np.clip's sums)
        lids = bool(self.field.eyelids)
        key = (contractions.tobytes(), joint.tobytes() if lids else b"")  # bytes: equal means identical
        kept = self._anchors_kept
        if kept is not None and kept[0] == key:
            anchors = kept[1]
        else:
            joint_deg = dict(zip(self.joint_names, joint.tolist(), strict=True)) if lids else None
            anchors = self._anchor_values(self.field.offsets_at(contractions, self._anchor_vertex, joint_deg))
            self._anchors_kept = (key, anchors)
        return dict(zip(self._target_plan[6], self._joint_values(joint) + anchors, strict=True))

    def _targets(self, joint: FloatArray, anchor_offsets: FloatArray) -> dict[str, float]:
        """Actuator targets from the joints (J,) and the anchor vertices' skin offsets (A, 3): a joint
        actuator's joints' mean, an anchor's pull along its line, each clamped to the actuator's range."""
        roles = self._target_plan[6]
        return dict(zip(roles, self._joint_values(joint) + self._anchor_values(anchor_offsets), strict=True))

    def _joint_values(self, joint: FloatArray) -> list[float]:
        """The joint actuators' targets (`_targets`' first part): each one's joints' mean, clamped."""
        first, multi, j_lo, j_hi = self._target_plan[:4]
        values = joint[first]  # a mean of one joint is that joint
        for k, cols, n in multi:  # `mean`'s sum and division, without its wrappers (n == 0: mean's NaN)
            values[k] = np.add.reduce(joint[cols]) / n if n else joint[cols].mean()
        out: list[float] = np.minimum(np.maximum(values, j_lo), j_hi).tolist()
        return out

    def _anchor_values(self, anchor_offsets: FloatArray) -> list[float]:
        """The anchor actuators' targets (`_targets`' second part): each pull along its line, clamped."""
        if not self.anchor_actuators:
            return []
        a_lo, a_hi = self._target_plan[4:6]
        pulls = np.einsum("ak,ak->a", anchor_offsets, self._anchor_line)
        out: list[float] = np.minimum(np.maximum(pulls, a_lo), a_hi).tolist()
        return out

    @cached_property
    def _target_plan(self) -> tuple[Any, ...]:
        """`_targets`' constants: each joint actuator's first joint column, the actuators with several joints,
        the ranges, and the roles in the targets' order (joint actuators, then anchors)."""
        first = np.array([int(c[0]) if c.size else 0 for c in self._joint_cols], dtype=np.int64)
        multi = [(k, c, int(c.size)) for k, c in enumerate(self._joint_cols) if c.size != 1]
        j_lo = np.array([a.lower_deg for a in self.joint_actuators], dtype=np.float64)
        j_hi = np.array([a.upper_deg for a in self.joint_actuators], dtype=np.float64)
        a_lo = np.array([a.lower_mm for a in self.anchor_actuators], dtype=np.float64)
        a_hi = np.array([a.upper_mm for a in self.anchor_actuators], dtype=np.float64)
        roles = [a.role for a in self.joint_actuators] + [a.role for a in self.anchor_actuators]
        return first, multi, j_lo, j_hi, a_lo, a_hi, roles

    # --- inverse: targets -> pose (the twin) ------------------------------------------------------------

    def pose_from_targets(self, targets: Mapping[str, float]) -> HeadPose:
        """The head the actuators produce: joints from joint targets, skin fitted to the anchor pulls.

        Roles missing from ``targets`` sit at their neutral. Unknown roles or non-finite values raise
        ``PoseError`` naming the role. Targets are clamped to the actuator and joint ranges.
        """
        clean: dict[str, float] = {}
        known = set(self.roles)
        for role, value in targets.items():
            if role not in known:
                raise PoseError(
                    f"actuator target {role!r}: not an actuator of head {self.head.name!r} ({sorted(known)})"
                )
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
                raise PoseError(f"actuator target {role!r}: expected a finite number, got {value!r}")
            if not math.isfinite(float(value)):
                raise PoseError(f"actuator target {role!r}: expected a finite number, got {value!r}")
            clean[role] = float(value)
        joint = self._neutral.copy()
        for act, cols in zip(self.joint_actuators, self._joint_cols, strict=True):
            value = min(max(clean.get(act.role, act.neutral_deg), act.lower_deg), act.upper_deg)
            clean[act.role] = value
            joint[cols] = value
        joint = np.clip(joint, self._lower, self._upper)
        joint_deg = dict(zip(self.joint_names, joint.tolist(), strict=True))
        pulls = np.array(
            [min(max(clean.get(a.role, a.neutral_mm), a.lower_mm), a.upper_mm) for a in self.anchor_actuators]
        )
        for anchor, pull in zip(self.anchor_actuators, pulls.tolist(), strict=True):
            clean[anchor.role] = pull
        contractions = self.fit.contractions(pulls) if pulls.size else np.zeros(len(self.field.names))
        offsets = self.field.offsets(contractions, joint_deg if self.field.eyelids else None)
        if pulls.size:
            got = np.einsum("ak,ak->a", offsets[self._anchor_vertex], self._anchor_line)
            offsets = offsets + self.fit.bumps(pulls - got)
        return HeadPose(joint_deg, offsets, clean)


def _values(items: Any) -> list[Any]:
    """Accept a tuple/list of records or a {name: record} mapping."""
    if isinstance(items, Mapping):
        return list(items.values())
    return list(items)


def benchmark_solve(head_name: str, n_frames: int = 500) -> list[float]:
    """Seconds per ``FaceModel.solve`` over ``n_frames`` varied AU frames of a built-in head (or profile).

    The frames cycle through the expression library's apex poses scaled by a slow sine, so every frame
    differs. These are the raw per-frame times, not a summary: take the median yourself,
    ``statistics.median(benchmark_solve("human", 500))`` (``servoface bench face`` prints it).
    """
    from servoface.sim.expressions import load_library
    from servoface.sim.heads import load_head

    head = load_head(head_name)
    model = FaceModel(head)
    library = load_library(getattr(head, "expressions_path", None) or head.face_type)
    apexes = [e.apex() for e in library.values()] or [{}]
    frames = []
    for i in range(max(n_frames, 1)):
        scale = 0.5 + 0.5 * math.sin(i * 0.1)
        frames.append({k: v * scale for k, v in apexes[i % len(apexes)].items()})
    for frame in frames[:10]:
        model.solve(frame)  # warm caches
    out = []
    for frame in frames[:n_frames]:
        t0 = time.perf_counter()
        model.solve(frame)
        out.append(time.perf_counter() - t0)
    return out
