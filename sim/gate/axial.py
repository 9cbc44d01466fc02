"""Distance tables for part pairs whose relative motion is a turn about one fixed line (a lid pair).

Both lids of an eye turn about the same axis through the eye centre (the upper lid's joint and the lower
lid's, axes along one line, possibly opposite): whatever the other joints do, the lower lid's pose in the
upper lid's frame is a rotation about that line by one signed sum s of the pair's own joints. The sphere
covers cannot tell the two shells apart (they slide past each other 0.16 mm apart), so the TSS flags the
pair and the exact test runs on most frames and finds nothing.

Instead, over a grid of s the table holds the exact mesh distance d_i (fcl, the same eroded meshes the exact
test uses) minus a margin. Turning one part about the line by Δ moves each of its points by at most
rho * |Δ| (rho: its largest vertex distance from the line; the distance to a line is convex, so a triangle's
points are no farther), so the distance at s is at least d_i - rho * |s - s_i|: where that is positive the
meshes are apart, the exact test would say so, and it is skipped. Outside the grid (beyond the joints'
box) the exact test runs as before. The build checks on poses of its own that the relative transform really
depends on s alone (otherwise no table).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.table_cache import cached_table

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

AXIAL_VERSION = "axial-2"  # in the cache file name: bump when the build changes
# rho * half a grid step (the slack a node gives away to the poses around it), coarse to fine: the lids'
# shells pass 0.16 mm apart, so their grid is the fine one; a pair apart by more keeps the coarse one
STEP_BUDGETS_MM = (0.5, 0.08)
MAX_NODES = 400
MARGIN_MM = 1e-3  # fcl's distance against its own collide near contact, and float rounding of s
MIN_CLEAR_SHARE = 0.5  # a table clearing fewer nodes than this does not pay for its lookup
_LINE_TOL = 1e-9  # axes parallel / pivots on the line (unit vectors, mm)
_CHECK_TOL = 1e-7  # the relative transform at random poses against the one at s alone


@dataclass(frozen=True)
class AxialTable:
    """One pair's distance table over the signed joint sum s (see the module docstring)."""

    joints: IntArray  # the pair's relative joints (tree indices)
    coef: FloatArray  # +-1 per joint: s = sum(coef * q)
    lower_deg: float  # s at node 0
    step_deg: float
    arm_mm: float  # rho, mm per rad of s
    slack_mm: FloatArray  # (n,) d_i - MARGIN_MM per node


def _line_coefs(tree: JointTree, chain_a: list[int], rel: list[int]) -> FloatArray | None:
    """+-1 per rel joint when all their axes lie on one line (B's joints +, A's -, by axis sense)."""
    if not rel:
        return None
    p0, u = tree.pivot_mm[rel[0]], tree.axis[rel[0]]
    coef = []
    for j in rel:
        a = tree.axis[j]
        if np.linalg.norm(np.cross(a, u)) > _LINE_TOL or np.linalg.norm(np.cross(tree.pivot_mm[j] - p0, u)) > 1e-6:
            return None
        coef.append(float(np.sign(np.dot(a, u))) * (-1.0 if j in chain_a else 1.0))
    return np.array(coef, dtype=np.float64)


def _relative(world: FloatArray, ja: int, jb: int) -> FloatArray:
    """(..., 4, 4) B's transform in A's frame."""
    eye = np.broadcast_to(np.eye(4), (*world.shape[:-3], 4, 4))
    ta = world[..., ja, :, :] if ja >= 0 else eye
    tb = world[..., jb, :, :] if jb >= 0 else eye
    return np.asarray(np.linalg.inv(ta) @ tb, dtype=np.float64)


def _at_s(tree: JointTree, rel: list[int], coef: FloatArray, s: FloatArray) -> FloatArray:
    """(n, J) poses (every joint 0 but the first rel joint) with the signed sum ``s``."""
    q = np.zeros((len(s), len(tree.names)))
    q[:, rel[0]] = s * coef[0]
    return q


def _line_arm_mm(vertices: FloatArray, p: FloatArray, u: FloatArray) -> float:
    return float(np.max(np.linalg.norm(np.cross(vertices - p, u), axis=1)))


def build_axial(
    tree: JointTree,
    joint_a: str | None,
    joint_b: str | None,
    rel: list[int],
    mesh_a: Any,
    mesh_b: Any,
    distance: Callable[[FloatArray, FloatArray], float],
) -> AxialTable | None:
    """The pair's table, or None (relative joints not on one line, or too few nodes clear). ``distance``
    (transform_a, transform_b) is the exact mesh distance of the pair's exact-test meshes."""
    chain_a = tree.chain(joint_a) if joint_a is not None else []
    coef = _line_coefs(tree, list(chain_a), rel)
    if coef is None:
        return None
    ja = -1 if joint_a is None else tree.index[joint_a]
    jb = -1 if joint_b is None else tree.index[joint_b]
    lo_q, hi_q = tree.lower_deg[rel], tree.upper_deg[rel]
    s_lo = float(np.sum(np.where(coef > 0, lo_q, -hi_q)))
    s_hi = float(np.sum(np.where(coef > 0, hi_q, -lo_q)))
    # the relative transform must be a function of s alone: random poses (every joint) against s alone
    rng = np.random.default_rng(0)
    q = rng.uniform(tree.lower_deg, tree.upper_deg, size=(16, len(tree.names)))
    s = q[:, rel] @ coef
    if not np.allclose(
        _relative(tree.world(q), ja, jb),
        _relative(tree.world(_at_s(tree, rel, coef, s)), ja, jb),
        rtol=0.0,
        atol=_CHECK_TOL,
    ):
        return None
    p0, u = tree.pivot_mm[rel[0]], tree.axis[rel[0]]
    va, vb = np.asarray(mesh_a.vertices, dtype=np.float64), np.asarray(mesh_b.vertices, dtype=np.float64)
    arm = min(_line_arm_mm(va, p0, u), _line_arm_mm(vb, p0, u))  # mm per rad of s
    eye = np.eye(4)
    for budget in STEP_BUDGETS_MM:  # coarse first: kept when it clears every pose in its grid
        step = float(np.rad2deg(2.0 * budget / max(arm, 1e-9)))
        n = int(np.ceil((s_hi - s_lo) / max(step, 1e-12))) + 1
        n = min(max(n, 2), MAX_NODES)
        step = (s_hi - s_lo) / (n - 1)
        nodes = np.asarray(s_lo + step * np.arange(n), dtype=np.float64)
        world = tree.world(_at_s(tree, rel, coef, nodes))
        d = np.array([distance(w[ja] if ja >= 0 else eye, w[jb] if jb >= 0 else eye) for w in world])
        slack = d - MARGIN_MM
        if float(slack.min()) > arm * np.deg2rad(step) / 2.0:
            break
    if np.mean(slack > 0.0) < MIN_CLEAR_SHARE:
        return None
    return AxialTable(np.array(rel, dtype=np.int64), coef, s_lo, step, arm, slack)


def _axial_from_npz(z: Mapping[str, Any]) -> AxialTable:
    return AxialTable(
        z["joints"].astype(np.int64),
        z["coef"],
        float(z["lower"]),
        float(z["step"]),
        float(z["arm"]),
        z["slack"],
    )


def _axial_npz_fields(table: AxialTable) -> dict[str, Any]:
    return {
        "joints": table.joints,
        "coef": table.coef,
        "lower": table.lower_deg,
        "step": table.step_deg,
        "arm": table.arm_mm,
        "slack": table.slack_mm,
    }


def cached_axial(path: Path | None, build: Callable[[], AxialTable | None]) -> AxialTable | None:
    """The table from ``path`` (named by the pair's TSS key and AXIAL_VERSION) or built and saved; a file
    that says "no table" is kept too. ``path`` None: build only."""
    return cached_table(path, build, kind="axial", load=_axial_from_npz, fields=_axial_npz_fields)


class AxialSet:
    """Every axial table of a head: `clear` for a batch of poses, `clear_one` for one (Python scalars)."""

    def __init__(self, pair_index: Sequence[int], tables: Sequence[AxialTable]) -> None:
        self.pair_index = np.array(pair_index, dtype=np.int64)
        self.tables = tuple(tables)
        t = len(self.tables)
        width = max([len(a.joints) for a in self.tables] + [1])
        self._joint = np.zeros((t, width), dtype=np.int64)
        self._coef = np.zeros((t, width))  # 0 pads
        for i, a in enumerate(self.tables):
            self._joint[i, : len(a.joints)] = a.joints
            self._coef[i, : len(a.joints)] = a.coef
        self._lo = np.array([a.lower_deg for a in self.tables])
        self._step = np.array([a.step_deg for a in self.tables])
        self._top = np.array([len(a.slack_mm) - 1 for a in self.tables], dtype=np.float64)
        self._arm = np.array([np.deg2rad(a.arm_mm) for a in self.tables])  # mm per deg
        self._base = np.cumsum([0] + [len(a.slack_mm) for a in self.tables])[:-1].astype(np.int64)
        self._slack = np.concatenate([a.slack_mm for a in self.tables]) if self.tables else np.zeros(0)
        self._rows = [
            (
                [(int(j), float(c)) for j, c in zip(a.joints, a.coef, strict=True)],
                float(a.lower_deg),
                float(a.step_deg),
                float(len(a.slack_mm) - 1),
                float(np.deg2rad(a.arm_mm)),
                a.slack_mm.tolist(),
            )
            for a in self.tables
        ]

    def __len__(self) -> int:
        return len(self.tables)

    def clear(self, angles_deg: FloatArray) -> BoolArray:
        """(..., T) True where table t proves its pair apart at the pose(s) ``angles_deg`` (..., J)."""
        s = np.sum(angles_deg[..., self._joint] * self._coef, axis=-1)  # (..., T)
        u = (s - self._lo) / self._step
        inside = (u >= -1e-9) & (u <= self._top + 1e-9)
        i = np.clip(np.rint(u), 0.0, self._top)
        moved = self._arm * np.abs(s - (self._lo + i * self._step))
        return np.asarray(inside & (self._slack[self._base + i.astype(np.int64)] > moved), dtype=bool)

    def clear_one(self, t: int, angles_deg: Sequence[float]) -> bool:
        """`clear` for table t and one pose (a list of floats): the same arithmetic in Python scalars."""
        terms, lo, step, top, arm, slack = self._rows[t]
        s = 0.0
        for j, c in terms:
            s += angles_deg[j] * c
        u = (s - lo) / step
        if u < -1e-9 or u > top + 1e-9:
            return False
        i = min(max(float(round(u)), 0.0), top)
        return bool(slack[int(i)] > arm * abs(s - (lo + i * step)))
