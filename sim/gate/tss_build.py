"""Tabulated Sphere Subsets, built offline (Navarro Newball 2010 ch. 8; muscle-models.md §9).

For each pair of rigid parts that can collide: cover both with spheres (`spheres.cover_spheres`), sweep a
grid over the joints that move one part relative to the other, and tabulate every sphere pair that ever
comes within ``r_a + r_b + margin`` at a grid node. ``margin`` bounds how far any sphere centre moves
between a grid node and any configuration in its cell (distance to the joint axis times half a step,
summed over joints; distances are bounded along the joint tree so the bound holds in every pose), so at
run time, anywhere inside the swept box, a sphere pair that is not in the table cannot touch. With the
spheres covering the surfaces, the table therefore misses no collision the exact triangle test finds.
Tables are cached per pair as ``.npz``, keyed by a hash of the meshes, the joint chain and the parameters.
"""

from __future__ import annotations

import hashlib
import itertools
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet, cover_spheres
from servoface.sim.gate.tss_sweep import balls_meet, grid_angles, sweep

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
TSS_VERSION = "tss-1"
_REFINE_ABOVE_NODES = 64  # larger grids go through the pyramid of `tss_refine` (a smaller one is its own top)


@dataclass(frozen=True)
class TssParams:
    """Build parameters: spheres per part, the margin budget (mm) that fixes the sweep step, caps."""

    spheres_per_part: int = 160
    max_cell_mm: float = 4.0  # large parts (a skull) get more spheres so none is coarser than this
    margin_mm: float = 0.6
    max_step_deg: float = 4.0
    max_grid_points: int = 12000
    chunk_elements: int = 4_000_000
    max_table_tests: int = 4000  # a pair with a larger table skips the spheres: exact test every frame
    max_margin_mm: float = 3.0  # a sweep this coarse (many joints) is not worth a table: exact test


@dataclass(frozen=True)
class PairTable:
    """The TSS of one part pair: sphere index pairs (ia into part a's spheres, ib into b's)."""

    a: str
    b: str
    joints: tuple[str, ...]
    lower_deg: FloatArray
    upper_deg: FloatArray
    ia: IntArray
    ib: IntArray
    n_all_pairs: int
    margin_mm: float
    step_deg: FloatArray
    grid_points: int
    tolerance_mm: float
    key: str
    exact_only: bool = False  # no table: the pair comes close somewhere and goes to the exact test

    @property
    def n_tests(self) -> int:
        return int(self.ia.shape[0])

    @property
    def reduction(self) -> float:
        """Share of sphere pairs that are never tested (1 - tests / all); 0 for an exact-only pair."""
        return 0.0 if self.exact_only else 1.0 - self.n_tests / max(self.n_all_pairs, 1)


def default_cache_dir() -> Path:
    env = os.environ.get("SERVOFACE_TSS_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "servoface" / "tss"


def _mesh_bytes(mesh: Any) -> bytes:
    v = np.ascontiguousarray(np.asarray(mesh.vertices, dtype=np.float64))
    f = np.ascontiguousarray(np.asarray(mesh.faces, dtype=np.int64))
    return v.tobytes() + f.tobytes()


def pair_key(
    tree: JointTree,
    part_a: Any,
    part_b: Any,
    mesh_a: Any,
    mesh_b: Any,
    tolerance_mm: float,
    params: TssParams,
) -> str:
    """Hash of everything a pair's table depends on."""
    h = hashlib.sha256(TSS_VERSION.encode())
    for part, mesh in ((part_a, mesh_a), (part_b, mesh_b)):
        h.update(part.name.encode())
        h.update(_mesh_bytes(mesh))
        for i in tree.chain(part.joint):
            h.update(tree.names[i].encode())
            h.update(np.array([*tree.pivot_mm[i], *tree.axis[i], tree.lower_deg[i], tree.upper_deg[i]]).tobytes())
    h.update(repr((tolerance_mm, params)).encode())
    return h.hexdigest()[:20]


def relative_joints(tree: JointTree, joint_a: str | None, joint_b: str | None) -> list[int]:
    """Joints that move part a relative to part b (the symmetric difference of their chains)."""
    ca, cb = tree.chain(joint_a), tree.chain(joint_b)
    return sorted(set(ca) ^ set(cb))


def _tree_distance_bound(tree: JointTree, from_joint: str | None, to_index: int) -> tuple[int, float]:
    """(start pivot index, summed pivot-to-pivot length) along the tree path from a part's joint to joint
    ``to_index``. For a part on the head base the path starts at the root of ``to_index``'s chain."""
    chain_to = tree.chain(tree.names[to_index])
    chain_from = tree.chain(from_joint) if from_joint is not None else [chain_to[-1]]
    common = next((i for i in chain_from if i in set(chain_to)), None)
    path_up = chain_from if common is None else chain_from[: chain_from.index(common) + 1]
    path_down = chain_to if common is None else chain_to[: chain_to.index(common) + 1]
    nodes = path_up + list(reversed(path_down))[1:] if common is not None else path_up + list(reversed(path_down))
    length = sum(float(np.linalg.norm(tree.pivot_mm[u] - tree.pivot_mm[v])) for u, v in itertools.pairwise(nodes))
    return chain_from[0], length


def lever_arm_mm(tree: JointTree, joint_name: str | None, spheres: SphereSet, j: int) -> float:
    """Upper bound (any pose) of the distance from a sphere surface point of a part to joint j's pivot."""
    start, length = _tree_distance_bound(tree, joint_name, j)
    reach = np.linalg.norm(spheres.centres_mm - tree.pivot_mm[start], axis=1) + spheres.radii_mm
    return float(reach.max()) + length


def sphere_arms_mm(tree: JointTree, joint_name: str | None, spheres: SphereSet, j: int) -> FloatArray:
    """`lever_arm_mm` per sphere (n,): a bound of how fast (mm per rad) joint j moves that sphere."""
    start, length = _tree_distance_bound(tree, joint_name, j)
    reach = np.linalg.norm(spheres.centres_mm - tree.pivot_mm[start], axis=1) + spheres.radii_mm
    return np.asarray(reach + length, dtype=np.float64)


def pair_lever_arms(
    tree: JointTree, joint_a: str | None, joint_b: str | None, sa: SphereSet, sb: SphereSet, rel: list[int]
) -> FloatArray:
    """(R,) per ``rel`` joint: `lever_arm_mm` of the part whose chain holds it (the TSS margin's arms)."""
    chain_a = set(tree.chain(joint_a))
    return np.array(
        [lever_arm_mm(tree, joint_a, sa, j) if j in chain_a else lever_arm_mm(tree, joint_b, sb, j) for j in rel]
    )


def pair_sphere_arms(
    tree: JointTree, joint_a: str | None, joint_b: str | None, sa: SphereSet, sb: SphereSet, rel: list[int]
) -> tuple[FloatArray, FloatArray]:
    """(n_a, R), (n_b, R): per sphere and ``rel`` joint, how fast (mm per rad) the joint moves that sphere
    (`sphere_arms_mm`), 0 where the joint is in the other part's chain (it moves the other part instead)."""
    chain_a = set(tree.chain(joint_a))
    arm_a, arm_b = np.zeros((sa.n, len(rel))), np.zeros((sb.n, len(rel)))
    for col, j in enumerate(rel):
        if j in chain_a:
            arm_a[:, col] = sphere_arms_mm(tree, joint_a, sa, j)
        else:
            arm_b[:, col] = sphere_arms_mm(tree, joint_b, sb, j)
    return arm_a, arm_b


def sweep_grid(
    lo: FloatArray, hi: FloatArray, arms: FloatArray, params: TssParams
) -> tuple[IntArray, FloatArray, float]:
    """(nodes per joint, step deg, margin mm) of a pair's sweep over the box [lo, hi]: steps that keep the
    in-cell motion within the margin budget, coarsened (finest axis first) to ``max_grid_points``."""
    budget = params.margin_mm / max(len(lo), 1)
    step = np.minimum(np.rad2deg(2.0 * budget / np.maximum(arms, 1e-9)), params.max_step_deg)
    counts = np.maximum(1, np.ceil((hi - lo) / np.maximum(step, 1e-9))).astype(np.int64) + 1
    while float(np.prod(counts.astype(np.float64))) > params.max_grid_points and np.any(counts > 2):
        i = int(np.argmax(counts))  # coarsen the finest axis first
        counts[i] = max(2, int(counts[i] * 0.85))
    step = np.where(counts > 1, (hi - lo) / np.maximum(counts - 1, 1), 0.0)
    return counts, step, float(np.sum(arms * np.deg2rad(step) / 2.0))


def build_pair(
    tree: JointTree,
    part_a: Any,
    part_b: Any,
    spheres_a: SphereSet,
    spheres_b: SphereSet,
    tolerance_mm: float,
    params: TssParams,
    key: str,
) -> PairTable:
    """Sweep the pair's relative joint space and tabulate the sphere pairs that can come close."""
    from servoface.sim.gate.tss_refine import pruned_balls_meet, refined_sweep

    rel = relative_joints(tree, part_a.joint, part_b.joint)
    arms = pair_lever_arms(tree, part_a.joint, part_b.joint, spheres_a, spheres_b, rel)
    lo = tree.lower_deg[rel]
    hi = tree.upper_deg[rel]
    counts, step, margin = sweep_grid(lo, hi, arms, params)
    ja = -1 if part_a.joint is None else tree.index[part_a.joint]
    jb = -1 if part_b.joint is None else tree.index[part_b.joint]
    coarse = margin > params.max_margin_mm
    n_grid = int(np.prod(counts)) if rel else 1
    ia = ib = np.zeros(0, dtype=np.int64)
    exact_only = False
    if coarse:  # no table either way: exact test every frame if the parts' bounding balls ever meet
        pad = margin + tolerance_mm
        if n_grid > _REFINE_ABOVE_NODES:
            exact_only = pruned_balls_meet(tree, rel, lo, hi, counts, part_a.joint, spheres_a, spheres_b, ja, jb, pad)
        else:
            exact_only = balls_meet(tree, grid_angles(tree, rel, lo, hi, counts), ja, jb, spheres_a, spheres_b, pad)
    else:
        pad, chunk = margin + tolerance_mm, params.chunk_elements
        if n_grid > _REFINE_ABOVE_NODES:  # seeded from coarser grids (`tss_refine`): the plain sweep's table
            arms_ab = pair_sphere_arms(tree, part_a.joint, part_b.joint, spheres_a, spheres_b, rel)
            hit = refined_sweep(tree, rel, lo, hi, counts, arms_ab, ja, jb, spheres_a, spheres_b, pad, chunk)
        else:
            hit = sweep(tree, grid_angles(tree, rel, lo, hi, counts), ja, jb, spheres_a, spheres_b, pad, chunk)
        ia, ib = np.nonzero(hit)
    return PairTable(
        part_a.name,
        part_b.name,
        tuple(tree.names[j] for j in rel),
        lo.copy(),
        hi.copy(),
        ia.astype(np.int64),
        ib.astype(np.int64),
        spheres_a.n * spheres_b.n,
        margin,
        step,
        n_grid,
        tolerance_mm,
        key,
        exact_only,
    )


@dataclass(frozen=True)
class BuiltPair:
    table: PairTable
    spheres_a: SphereSet
    spheres_b: SphereSet
    from_cache: bool


def build_or_load(
    tree: JointTree,
    head_name: str,
    part_a: Any,
    part_b: Any,
    mesh_a: Any,
    mesh_b: Any,
    tolerance_mm: float,
    params: TssParams,
    cache_dir: Path | None,
    covers: dict[int, tuple[Any, SphereSet]] | None = None,
) -> BuiltPair:
    """The pair's table from the cache when its key matches, else built (and cached when a dir is given).

    ``covers``: spheres already computed for a mesh object (by ``id``, the mesh held beside them), shared
    by the pairs of one build: a part in many pairs is covered once (`cover_spheres` is deterministic)."""
    key = pair_key(tree, part_a, part_b, mesh_a, mesh_b, tolerance_mm, params)
    from servoface.sim.gate.tss_cache import load_table, save_table

    path = None if cache_dir is None else cache_dir / f"{head_name}-{part_a.name}-{part_b.name}-{key}.npz"
    if path is not None:
        got = load_table(path, key)
        if got is not None:
            return BuiltPair(got[0], got[1], got[2], True)
    sa = _covered(mesh_a, params, covers)
    sb = _covered(mesh_b, params, covers)
    table = build_pair(tree, part_a, part_b, sa, sb, tolerance_mm, params, key)
    if path is not None:
        save_table(path, table, sa, sb)
    return BuiltPair(table, sa, sb, False)


def _covered(mesh: Any, params: TssParams, covers: dict[int, tuple[Any, SphereSet]] | None) -> SphereSet:
    if covers is not None and id(mesh) in covers and covers[id(mesh)][0] is mesh:
        return covers[id(mesh)][1]
    spheres = cover_spheres(mesh, params.spheres_per_part, max_cell_mm=params.max_cell_mm)
    if covers is not None:
        covers[id(mesh)] = (mesh, spheres)
    return spheres


def summed_reduction(tables: Sequence[PairTable]) -> float:
    """1 - (tested sphere pairs) / (all sphere pairs), over every pair the spheres handle (exact-only
    pairs left out: they have no table)."""
    tests = sum(t.n_tests for t in tables if not t.exact_only)
    total = sum(t.n_all_pairs for t in tables if not t.exact_only)
    return 1.0 - tests / max(total, 1)
