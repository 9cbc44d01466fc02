"""Tabulated clearance for part pairs that have no TSS table and whose bounding balls always meet.

Such a pair (the dog's jaw against an eyeball, a lid, the upper teeth against the tongue tip) would go to
the exact mesh test every frame. Instead: one part X is kept inside a ball about a point c that the joints
moving X relative to the other part Y (nearest X first) all turn about, so the ball does not move with
them; the remaining relative joints K move c relative to Y. Over a grid of K the table holds a lower bound
of the distance from c to Y's surface minus the ball's radius (the "slack", from Y's covering spheres: every
surface point lies in a sphere, so min |c - s_i| - r_i bounds it from below). At run time, for the grid node
nearest the pose: when the node's slack exceeds how far c can have moved from the node (joint lever arms
along the tree times the angle offsets), X's triangles lie inside the ball and Y's outside it, so no
triangle of X meets one of Y: the exact test would say "apart", and it is skipped. Otherwise (or outside
the grid's box) the exact test runs as before, so the gate's verdicts do not change.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.proofs import common_centre
from servoface.sim.gate.spheres import SphereSet
from servoface.sim.gate.table_cache import cached_table
from servoface.sim.gate.tss_build import lever_arm_mm, relative_joints
from servoface.sim.gate.tss_sweep import grid_angles

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

CLEARANCE_VERSION = "clear-2"  # in the cache file name: bump when the build changes
CELL_BOUND_MM = 2.0  # how far c may move between a grid node and any pose in its cell (all K joints)
MAX_NODES = 4000
MAX_TABLE_JOINTS = 3
MIN_CLEAR_SHARE = 0.5  # a table clearing fewer grid nodes than this does not pay for its lookup
_CHUNK_NODES = 512
_NEAREST = 8
_SLACK_MM = 1e-5  # float rounding and common_centre's 1e-6 mm tolerance


@dataclass(frozen=True)
class Clearance:
    """One pair's clearance table (see the module docstring)."""

    ball_part: str
    centre_mm: FloatArray  # c, head frame at rest
    radius_mm: float  # X's (eroded) vertices lie within this of c
    joints: IntArray  # K, tree indices
    lower_deg: FloatArray
    step_deg: FloatArray
    counts: IntArray
    arm_mm: FloatArray  # per K joint: c moves at most this many mm per rad of it, relative to Y
    slack_mm: FloatArray  # (prod counts,) row-major over K: lower bound of dist(c, Y) - radius

    @property
    def proven_apart(self) -> bool:
        """Whether every pose inside the grid's box is clear (slack beats the largest in-cell motion)."""
        cell = float(np.sum(self.arm_mm * np.deg2rad(self.step_deg) / 2.0))
        return bool(self.slack_mm.min() > cell)


def _ball_side(tree: JointTree, x: Any, y: Any, mesh_x: Any) -> tuple[FloatArray, float, list[int]]:
    """(c, radius, K) for part x kept in a ball against part y."""
    chain_y = set(tree.chain(y.joint))
    own = [j for j in tree.chain(x.joint) if j not in chain_y]  # x's joint first, upwards
    v = np.asarray(mesh_x.vertices, dtype=np.float64)
    c = (v.min(axis=0) + v.max(axis=0)) / 2.0
    fixed: list[int] = []
    for n in range(1, len(own) + 1):
        if n == 1:  # one axis: the point on it nearest the part's box centre
            p, a = tree.pivot_mm[own[0]], tree.axis[own[0]]
            cand: FloatArray | None = p + a * float(np.dot(c - p, a))
        else:
            cand = common_centre(tree, own[:n])
        if cand is None:
            break
        c, fixed = np.asarray(cand, dtype=np.float64), own[:n]
    radius = float(np.max(np.linalg.norm(v - c, axis=1)))
    rel = relative_joints(tree, x.joint, y.joint)
    return c, radius, [j for j in rel if j not in fixed]


def build_clearance(
    tree: JointTree, part_a: Any, part_b: Any, mesh_a: Any, mesh_b: Any, spheres_a: SphereSet, spheres_b: SphereSet
) -> Clearance | None:
    """The pair's clearance table, or None when no side gives one worth having (too many joints left, or
    no grid node clear at all). Deterministic in the meshes, spheres and joint tree."""
    options = []
    for x, y, mx, sy in ((part_b, part_a, mesh_b, spheres_a), (part_a, part_b, mesh_a, spheres_b)):
        c, radius, k = _ball_side(tree, x, y, mx)
        if len(k) <= MAX_TABLE_JOINTS:
            options.append((len(k), radius, x, y, c, k, sy))
    if not options:
        return None
    _, radius, x, y, c, k, sy = min(options, key=lambda o: (o[1], o[0]))  # the smaller ball
    point = SphereSet(c[None, :], np.zeros(1))
    arms = np.array([lever_arm_mm(tree, x.joint, point, j) for j in k], dtype=np.float64).reshape(-1)
    lo, hi = tree.lower_deg[k], tree.upper_deg[k]
    budget = CELL_BOUND_MM / max(len(k), 1)
    step = np.rad2deg(2.0 * budget / np.maximum(arms, 1e-9))
    counts = np.maximum(1, np.ceil((hi - lo) / np.maximum(step, 1e-9))).astype(np.int64) + 1
    while float(np.prod(counts.astype(np.float64))) > MAX_NODES and np.any(counts > 2):
        i = int(np.argmax(counts))
        counts[i] = max(2, int(counts[i] * 0.85))
    step = np.where(counts > 1, (hi - lo) / np.maximum(counts - 1, 1), 0.0)
    angles = grid_angles(tree, k, lo, hi, counts)
    from scipy.spatial import cKDTree

    jx = -1 if x.joint is None else tree.index[x.joint]
    jy = -1 if y.joint is None else tree.index[y.joint]
    slack = np.empty(angles.shape[0])
    kd = cKDTree(sy.centres_mm)
    ch = np.r_[c, 1.0]
    for s in range(0, angles.shape[0], _CHUNK_NODES):
        world = tree.world_of(angles[s : s + _CHUNK_NODES], (jx, jy))  # `world` along the two chains only
        g = world.shape[0]
        tx = world[:, jx] if jx >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
        ty = world[:, jy] if jy >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
        p = (np.linalg.inv(ty) @ (tx @ ch)[..., None])[:, :3, 0]  # c in y's rest frame
        slack[s : s + g] = _surface_gap_lower_mm(kd, sy, p) - radius
    slack -= _SLACK_MM  # c sits on the axes to common_centre's tolerance
    if np.mean(slack > 0.0) < MIN_CLEAR_SHARE:
        return None
    return Clearance(
        x.name,
        c,
        radius,
        np.array(k, dtype=np.int64),
        lo.copy(),
        step,
        counts,
        arms,
        slack,
    )


def _surface_gap_lower_mm(kd: Any, spheres: SphereSet, points: FloatArray) -> FloatArray:
    """(n,) lower bound of each point's distance to the surface the spheres cover: min_i |p - c_i| - r_i
    over the NEAREST centres, and (nearest-th distance - largest radius) for every other sphere."""
    k = min(_NEAREST, spheres.n)
    dist, idx = kd.query(points, k=k)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    near = np.min(dist - spheres.radii_mm[idx], axis=1)
    if k < spheres.n:
        near = np.minimum(near, dist[:, -1] - float(spheres.radii_mm.max()))
    return np.asarray(near, dtype=np.float64)


def _clearance_from_npz(z: Mapping[str, Any]) -> Clearance:
    return Clearance(
        str(z["ball_part"]),
        z["centre"],
        float(z["radius"]),
        z["joints"].astype(np.int64),
        z["lower"],
        z["step"],
        z["counts"].astype(np.int64),
        z["arm"],
        z["slack"],
    )


def _clearance_npz_fields(table: Clearance) -> dict[str, Any]:
    return {
        "ball_part": table.ball_part,
        "centre": table.centre_mm,
        "radius": table.radius_mm,
        "joints": table.joints,
        "lower": table.lower_deg,
        "step": table.step_deg,
        "counts": table.counts,
        "arm": table.arm_mm,
        "slack": table.slack_mm,
    }


def cached_clearance(path: Path | None, build: Callable[[], Clearance | None]) -> Clearance | None:
    """The table from ``path`` (named by the pair's TSS key and CLEARANCE_VERSION) or built and saved;
    a file that says "no table" is kept too. ``path`` None: build only."""
    return cached_table(path, build, kind="clearance", load=_clearance_from_npz, fields=_clearance_npz_fields)


class GridTable(Protocol):
    """What `ClearanceSet` reads of a table: a regular grid over some joints, per-node slack (mm) and per
    joint the mm per rad a pose's offset from its nearest node can eat of it (`Clearance`,
    `joint_tables.DistanceTable`)."""

    @property
    def joints(self) -> IntArray: ...
    @property
    def lower_deg(self) -> FloatArray: ...
    @property
    def step_deg(self) -> FloatArray: ...
    @property
    def counts(self) -> IntArray: ...
    @property
    def arm_mm(self) -> FloatArray: ...
    @property
    def slack_mm(self) -> FloatArray: ...
    @property
    def proven_apart(self) -> bool: ...


class ClearanceSet:
    """Every clearance table of a head, evaluated together (a handful of numpy calls per batch, a short
    Python loop over the tables whose balls met for one pose)."""

    def __init__(self, pair_index: Sequence[int], tables: Sequence[GridTable]) -> None:
        self.pair_index = np.array(pair_index, dtype=np.int64)
        self.tables = tuple(tables)
        self.proven = np.array([c.proven_apart for c in self.tables], dtype=bool)
        t = len(self.tables)
        width = max([len(c.joints) for c in self.tables] + [1])
        self._joint = np.zeros((t, width), dtype=np.int64)
        self._lo = np.zeros((t, width))
        self._step = np.ones((t, width))
        self._top = np.zeros((t, width))  # last node index per joint
        self._stride = np.zeros((t, width), dtype=np.int64)
        self._arm = np.zeros((t, width))  # mm per deg
        self._valid = np.zeros((t, width), dtype=bool)
        base = []
        offset = 0
        for i, c in enumerate(self.tables):
            n = len(c.joints)
            self._joint[i, :n] = c.joints
            self._lo[i, :n] = c.lower_deg
            self._step[i, :n] = np.where(c.step_deg > 0, c.step_deg, 1.0)
            self._top[i, :n] = np.where(c.step_deg > 0, c.counts - 1, 0)  # a joint without range: its node 0 only
            self._stride[i, :n] = np.cumprod(np.r_[1, c.counts[1:][::-1]])[::-1] if n else []
            self._arm[i, :n] = np.deg2rad(c.arm_mm)
            self._valid[i, :n] = True
            base.append(offset)
            offset += len(c.slack_mm)
        self._base = np.array(base, dtype=np.int64)
        self._slack = np.concatenate([c.slack_mm for c in self.tables]) if self.tables else np.zeros(0)
        # per table, per joint: (joint, lo, step, top, stride, arm) as Python scalars for `clear_one`
        self._rows: list[list[tuple[int, float, float, float, int, float]]] = [
            [
                (
                    int(self._joint[i, w]),
                    float(self._lo[i, w]),
                    float(self._step[i, w]),
                    float(self._top[i, w]),
                    int(self._stride[i, w]),
                    float(self._arm[i, w]),
                )
                for w in range(len(c.joints))
            ]
            for i, c in enumerate(self.tables)
        ]
        self._slack_list = [c.slack_mm.tolist() for c in self.tables]

    def __len__(self) -> int:
        return len(self.tables)

    def clear(self, angles_deg: FloatArray) -> BoolArray:
        """(..., T) True where table t proves its pair apart at the pose(s) ``angles_deg`` (..., J)."""
        q = angles_deg[..., self._joint]  # (..., T, W)
        u = (q - self._lo) / self._step
        inside = ((u >= -1e-9) & (u <= self._top + 1e-9)) | ~self._valid
        i = np.clip(np.rint(u), 0.0, self._top)
        moved = np.sum(self._arm * np.abs(q - (self._lo + i * self._step)), axis=-1)
        flat = self._base + np.sum(i.astype(np.int64) * self._stride, axis=-1)
        return np.asarray(inside.all(axis=-1) & (self._slack[flat] > moved), dtype=bool)

    def clear_one(self, t: int, angles_deg: Sequence[float]) -> bool:
        """`clear` for table t and one pose (a list of floats): the same arithmetic in Python scalars."""
        moved = 0.0
        flat = 0
        for j, lo, step, top, stride, arm in self._rows[t]:
            u = (angles_deg[j] - lo) / step
            if u < -1e-9 or u > top + 1e-9:
                return False
            i = min(max(float(round(u)), 0.0), top)
            moved += arm * abs(angles_deg[j] - (lo + i * step))
            flat += int(i) * stride
        return bool(self._slack_list[t][flat] > moved)
