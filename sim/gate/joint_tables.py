"""Exact cheaper treatments for part pairs the broad phase keeps flagging although they never meet.

Distance tables. A pair moved relative to each other by at most two joints K (the dog's ear on its pan and
tilt joints against the skull) is flagged by the TSS whenever its spheres overlap, which for a part seated
on another is most of the time, and the exact test then finds nothing. Over a grid of K the table holds the
exact mesh distance d_i (fcl, the same eroded meshes the exact test uses) minus a margin. The relative pose
of the two parts is a function of K alone (the joints both chains share move both parts alike); changing
joint k by Δ moves the part whose chain holds k by at most arm_k |Δ| (`tss_build.lever_arm_mm` of its
vertices: any point of a triangle is no farther from the pivot than its farthest corner). So at a pose q
inside the grid's box the distance is at least d_i - sum_k arm_k |q_k - node_k|: where that is positive
the exact test would say "apart", and it is skipped (`clearance.ClearanceSet` evaluates the tables). Outside
the box (joints beyond their limits) the exact test runs as before.

Separating planes. Two parts that each turn on their own joints below a common ancestor (the dog's two
ears) keep to the two sides of a plane in that ancestor's frame when, over every pose of their own joints,
one part's vertices stay beyond it and the other's before it (the extreme of a linear function over a
triangle is at a corner). Over a grid of each part's own joints the extreme is exact at the nodes and
grows by at most sum_k arm_k * half a step between them. Such a pair cannot meet in any pose inside the
joint limits (the common joints move both alike), so it needs no exact test there.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet
from servoface.sim.gate.table_cache import cached_table
from servoface.sim.gate.tss_build import lever_arm_mm
from servoface.sim.gate.tss_sweep import grid_angles

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

DISTANCE_VERSION = "jdist-2"  # in the cache file name: bump when the build changes
MAX_JOINTS = 2
MAX_NODES = 20000
# sum_k arm_k * half a step (what a node gives away to the poses around it): the exact distance on the
# coarse grid, then on the fine grid where the coarse bound does not clear it
COARSE_BUDGET_MM = 4.0
FINE_BUDGET_MM = 1.0
MARGIN_MM = 1e-3  # fcl's distance against its own collide near contact, and float rounding of the pose
MIN_CLEAR_SHARE = 0.5  # a table clearing fewer nodes than this does not pay for its lookup
PLANE_STEP_BUDGET_MM = 1.0
PLANE_COARSE_BUDGET_MM = 8.0
PLANE_MARGIN_MM = 1e-6  # float rounding of the posed vertices (mm-scale coordinates, float64)


@dataclass(frozen=True)
class DistanceTable:
    """One pair's distance table over its relative joints (see the module docstring); the fields
    `clearance.ClearanceSet` reads."""

    joints: IntArray  # K, tree indices
    lower_deg: FloatArray
    step_deg: FloatArray
    counts: IntArray
    arm_mm: FloatArray  # per K joint: mm per rad it moves the part whose chain holds it
    slack_mm: FloatArray  # (prod counts,) row-major over K: exact distance - MARGIN_MM

    @property
    def proven_apart(self) -> bool:
        """Whether every pose inside the grid's box is clear."""
        cell = float(np.sum(self.arm_mm * np.deg2rad(self.step_deg) / 2.0))
        return bool(self.slack_mm.min() > cell)


def _vertex_arm_mm(tree: JointTree, joint: str | None, mesh: Any, j: int) -> float:
    v = np.asarray(mesh.vertices, dtype=np.float64)
    return lever_arm_mm(tree, joint, SphereSet(v, np.zeros(len(v))), j)


def _grid_counts(arms: FloatArray, lo: FloatArray, hi: FloatArray, budget_mm: float) -> IntArray:
    """Nodes per joint so that sum_k arm_k * half a step <= budget (each joint an equal share)."""
    step = np.rad2deg(2.0 * budget_mm / len(arms) / np.maximum(arms, 1e-9))
    return np.maximum(2, np.ceil((hi - lo) / np.maximum(step, 1e-12)).astype(np.int64) + 1)


def build_distance_table(
    tree: JointTree,
    joint_a: str | None,
    joint_b: str | None,
    rel: list[int],
    mesh_a: Any,
    mesh_b: Any,
    distance: Callable[[FloatArray, FloatArray], float],
) -> DistanceTable | None:
    """The pair's table, or None (more than MAX_JOINTS relative joints, too many nodes, or too few nodes
    clear). ``distance`` (transform_a, transform_b): the exact mesh distance of the pair's exact-test meshes.

    Built in two levels: the exact distance on a coarse grid (COARSE_BUDGET_MM), then a fine grid through
    the coarse nodes (FINE_BUDGET_MM) whose nodes take the nearest coarse node's slack minus how far the
    parts can move between the two (a lower bound of their distance, so a sound slack) where that already
    clears the fine cell, and the exact distance elsewhere (near contact)."""
    if not rel or len(rel) > MAX_JOINTS:
        return None
    chain_a = set(tree.chain(joint_a))
    arms = np.array(
        [
            _vertex_arm_mm(tree, joint_a, mesh_a, j) if j in chain_a else _vertex_arm_mm(tree, joint_b, mesh_b, j)
            for j in rel
        ]
    )
    lo, hi = tree.lower_deg[rel], tree.upper_deg[rel]
    ja = -1 if joint_a is None else tree.index[joint_a]
    jb = -1 if joint_b is None else tree.index[joint_b]
    eye = np.eye(4)

    def exact(q: FloatArray) -> FloatArray:
        world = tree.world_of(q, (ja, jb))
        d = [distance(w[ja] if ja >= 0 else eye, w[jb] if jb >= 0 else eye) for w in world]
        return np.asarray(d, dtype=np.float64) - MARGIN_MM

    coarse = _grid_counts(arms, lo, hi, COARSE_BUDGET_MM)
    ratio = int(np.ceil(COARSE_BUDGET_MM / FINE_BUDGET_MM))
    fine = (coarse - 1) * ratio + 1  # every coarse node is a fine node
    if float(np.prod(fine.astype(np.float64))) > MAX_NODES:
        return None
    step = (hi - lo) / (fine - 1)
    coarse_slack = exact(grid_angles(tree, rel, lo, hi, coarse)).reshape(tuple(coarse))
    # fine node -> nearest coarse node, per joint, and how far (deg) it is from it
    idx = [np.arange(n) for n in fine]
    near = [np.rint(i / ratio).astype(np.int64) for i in idx]
    off = [np.abs(i - ratio * c) * st for i, c, st in zip(idx, near, step, strict=True)]
    inherited = coarse_slack[np.ix_(*near)]
    for k in range(len(rel)):
        shape = [1] * len(rel)
        shape[k] = -1
        inherited = inherited - arms[k] * np.deg2rad(off[k]).reshape(shape)
    slack = inherited.reshape(-1)
    cell = float(np.sum(arms * np.deg2rad(step) / 2.0))
    redo = np.flatnonzero(slack <= cell)  # too close to contact to be cleared by the bound: measured
    if len(redo):
        slack[redo] = exact(grid_angles(tree, rel, lo, hi, fine)[redo])
    if np.mean(slack > 0.0) < MIN_CLEAR_SHARE:
        return None
    return DistanceTable(np.array(rel, dtype=np.int64), lo.copy(), step, fine, arms, np.asarray(slack))


def _distance_from_npz(z: Mapping[str, Any]) -> DistanceTable:
    return DistanceTable(
        z["joints"].astype(np.int64), z["lower"], z["step"], z["counts"].astype(np.int64), z["arm"], z["slack"]
    )


def _distance_npz_fields(table: DistanceTable) -> dict[str, Any]:
    return {
        "joints": table.joints,
        "lower": table.lower_deg,
        "step": table.step_deg,
        "counts": table.counts,
        "arm": table.arm_mm,
        "slack": table.slack_mm,
    }


def cached_distance(path: Path | None, build: Callable[[], DistanceTable | None]) -> DistanceTable | None:
    """The table from ``path`` (named by the pair's TSS key and DISTANCE_VERSION) or built and saved."""
    return cached_table(path, build, kind="distance", load=_distance_from_npz, fields=_distance_npz_fields)


def _extent_mm(
    tree: JointTree, joint: str | None, own: list[int], mesh: Any, normal: FloatArray, budget_mm: float
) -> tuple[float, float]:
    """(lowest, highest) bound of normal . x over the part's vertices and every pose of its ``own`` joints
    inside their limits, in the frame of the joint above them (the other joints at 0); the grid's cell
    gives away at most ``budget_mm``."""
    v = np.c_[np.asarray(mesh.vertices, dtype=np.float64), np.ones(len(mesh.vertices))]
    if not own:
        h = v[:, :3] @ normal
        return float(h.min()), float(h.max())
    arms = np.array([_vertex_arm_mm(tree, joint, mesh, j) for j in own])
    lo, hi = tree.lower_deg[own], tree.upper_deg[own]
    counts = _grid_counts(arms, lo, hi, budget_mm)
    step = (hi - lo) / (counts - 1)
    cell = float(np.sum(arms * np.deg2rad(step) / 2.0)) + PLANE_MARGIN_MM
    j = tree.index[joint] if joint is not None else -1
    low, high = np.inf, -np.inf
    q = grid_angles(tree, own, lo, hi, counts)
    for s in range(0, len(q), 1024):
        world = tree.world_of(q[s : s + 1024], (j,))[:, j]  # (g, 4, 4)
        h = np.einsum("i,gij->gj", normal, world[:, :3, :]) @ v.T  # (g, nv): normal . (world @ v)
        low, high = min(low, float(h.min())), max(high, float(h.max()))
    return low - cell, high + cell


def plane_separated(tree: JointTree, joint_a: str | None, joint_b: str | None, mesh_a: Any, mesh_b: Any) -> str | None:
    """A reason string when the parts keep to two sides of a plane in every pose inside the joint limits
    (see the module docstring), else None. Tried only when each part has at most MAX_JOINTS own joints
    below the joints they share, on the plane normal to the line between their rest boxes' centres."""
    chain_a, chain_b = tree.chain(joint_a), tree.chain(joint_b)
    shared = set(chain_a) & set(chain_b)
    own_a = [j for j in chain_a if j not in shared]
    own_b = [j for j in chain_b if j not in shared]
    if len(own_a) > MAX_JOINTS or len(own_b) > MAX_JOINTS or not (own_a or own_b):
        return None
    va, vb = np.asarray(mesh_a.vertices, dtype=np.float64), np.asarray(mesh_b.vertices, dtype=np.float64)
    centre_a = (va.min(axis=0) + va.max(axis=0)) / 2.0
    centre_b = (vb.min(axis=0) + vb.max(axis=0)) / 2.0
    gap = centre_a - centre_b
    if float(np.linalg.norm(gap)) < 1e-9:
        return None
    normal = gap / np.linalg.norm(gap)
    for budget in (PLANE_COARSE_BUDGET_MM, PLANE_STEP_BUDGET_MM):  # coarse first: most pairs stop there
        a_lo, _ = _extent_mm(tree, joint_a, own_a, mesh_a, normal, budget)
        _, b_hi = _extent_mm(tree, joint_b, own_b, mesh_b, normal, budget)
        if b_hi < a_lo:
            return (
                f"kept to two sides of a plane (normal {np.round(normal, 3).tolist()}: one part's vertices at "
                f">= {a_lo:.2f} mm, the other's at <= {b_hi:.2f} mm over their own joints' limits): cannot collide"
            )
        if a_lo + budget < b_hi - budget:  # poses on the grid already overlap along the normal: no finer grid helps
            return None
    return None
