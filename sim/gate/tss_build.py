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

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
TSS_VERSION = "tss-1"
REFINE_FACTOR = 2.0  # the fine sweep is seeded from a grid this much coarser per axis (`tss_refine`)
_FILTER_SLACK_MM = 1e-6  # pre-filters keep a candidate this far beyond their bound (float rounding)


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
    rel = relative_joints(tree, part_a.joint, part_b.joint)
    chain_a = set(tree.chain(part_a.joint))
    arms = np.array(
        [
            lever_arm_mm(tree, part_a.joint, spheres_a, j)
            if j in chain_a
            else lever_arm_mm(tree, part_b.joint, spheres_b, j)
            for j in rel
        ]
    )
    lo = tree.lower_deg[rel]
    hi = tree.upper_deg[rel]
    budget = params.margin_mm / max(len(rel), 1)
    step = np.minimum(np.rad2deg(2.0 * budget / np.maximum(arms, 1e-9)), params.max_step_deg)
    counts = np.maximum(1, np.ceil((hi - lo) / np.maximum(step, 1e-9))).astype(np.int64) + 1
    while float(np.prod(counts.astype(np.float64))) > params.max_grid_points and np.any(counts > 2):
        i = int(np.argmax(counts))  # coarsen the finest axis first
        counts[i] = max(2, int(counts[i] * 0.85))
    step = np.where(counts > 1, (hi - lo) / np.maximum(counts - 1, 1), 0.0)
    margin = float(np.sum(arms * np.deg2rad(step) / 2.0))
    ja = -1 if part_a.joint is None else tree.index[part_a.joint]
    jb = -1 if part_b.joint is None else tree.index[part_b.joint]
    coarse = margin > params.max_margin_mm
    n_grid = int(np.prod(counts)) if rel else 1
    ia = ib = np.zeros(0, dtype=np.int64)
    exact_only = False
    if coarse:  # no table either way: exact test every frame if the parts' bounding balls ever meet
        exact_only = _balls_meet(
            tree, _grid_angles(tree, rel, lo, hi, counts), ja, jb, spheres_a, spheres_b, margin + tolerance_mm
        )
    else:
        # coarse to fine: a sweep at a quarter of the resolution (its larger margin keeps it conservative)
        # finds the spheres that can come close at all; the fine sweep only queries those
        cand_a = np.ones(spheres_a.n, dtype=bool)
        cand_b = np.ones(spheres_b.n, dtype=bool)
        if n_grid > 1000:
            c_counts = np.maximum(2, np.ceil(counts / 4.0)).astype(np.int64)
            c_step = np.where(c_counts > 1, (hi - lo) / np.maximum(c_counts - 1, 1), 0.0)
            c_margin = float(np.sum(arms * np.deg2rad(c_step) / 2.0))
            c_hit = _sweep(
                tree,
                _grid_angles(tree, rel, lo, hi, c_counts),
                ja,
                jb,
                spheres_a,
                spheres_b,
                c_margin + tolerance_mm,
                params.chunk_elements,
            )
            cand_a, cand_b = np.asarray(c_hit.any(axis=1)), np.asarray(c_hit.any(axis=0))
        if cand_a.any() and cand_b.any():
            ia_c, ib_c = np.flatnonzero(cand_a), np.flatnonzero(cand_b)
            sa_c, sb_c = _subset(spheres_a, ia_c), _subset(spheres_b, ib_c)
            pad, chunk = margin + tolerance_mm, params.chunk_elements
            if n_grid > 1000:  # each fine node tests only the pairs found near its coarse node (same table)
                from servoface.sim.gate.tss_refine import refined_sweep

                r_counts = np.maximum(2, np.ceil(counts / REFINE_FACTOR)).astype(np.int64)
                r_step = np.where(r_counts > 1, (hi - lo) / np.maximum(r_counts - 1, 1), 0.0)
                r_margin = float(np.sum(arms * np.deg2rad(r_step) / 2.0))
                sub = refined_sweep(tree, rel, lo, hi, counts, r_counts, r_margin, ja, jb, sa_c, sb_c, pad, chunk)
            else:
                sub = _sweep(tree, _grid_angles(tree, rel, lo, hi, counts), ja, jb, sa_c, sb_c, pad, chunk)
            si, sj = np.nonzero(sub)  # row-major, as np.nonzero of the full (n_a, n_b) matrix would be
            ia, ib = ia_c[si], ib_c[sj]
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


def _grid_angles(tree: JointTree, rel: list[int], lo: FloatArray, hi: FloatArray, counts: IntArray) -> FloatArray:
    """(G, J) joint angles of a regular grid over the ``rel`` joints (others at 0)."""
    axes = [np.linspace(lo[i], hi[i], int(counts[i])) for i in range(len(rel))]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(rel)) if rel else np.zeros((1, 0))
    angles = np.zeros((grid.shape[0], len(tree.names)))
    angles[:, rel] = grid
    return angles


def _subset(spheres: SphereSet, idx: IntArray) -> SphereSet:
    return SphereSet(spheres.centres_mm[idx], spheres.radii_mm[idx])


def _sweep(
    tree: JointTree,
    angles: FloatArray,
    ja: int,
    jb: int,
    sa: SphereSet,
    sb: SphereSet,
    pad_mm: float,
    chunk: int,
) -> NDArray[np.bool_]:
    """(n_a, n_b) True where spheres i of a and j of b come within r_i + r_j + pad at some grid node.

    Works in b's rest frame (a's centres moved by inv(T_b) T_a), so b's k-d tree is built once; grid
    nodes where the two parts' bounding balls stay apart are skipped.
    """
    from scipy.spatial import cKDTree

    hit = np.zeros((sa.n, sb.n), dtype=bool)
    kd = cKDTree(sb.centres_mm)
    ha = np.c_[sa.centres_mm, np.ones(sa.n)]
    rmax_b = float(sb.radii_mm.max())
    cb_ball, rb_ball = _bounding_ball(sb)
    per_chunk = max(1, chunk // max(sa.n, 1))
    for start in range(0, angles.shape[0], per_chunk):
        rel, near = _near_nodes(tree, angles[start : start + per_chunk], ja, jb, sa, sb, pad_mm)
        if not near.any():
            continue
        pts = np.einsum("gij,nj->gni", rel[near], ha)[..., :3].reshape(-1, 3)
        idx_a = np.tile(np.arange(sa.n), int(near.sum()))
        if sa.n > 2 * sb.n:  # fewer queries from b's side: candidates found in a's frame
            rows, cols = _candidates_from_b(rel[near], sa, sb, pad_mm)
        else:
            rows, cols = _candidates_from_a(pts, idx_a, kd, sa, sb, cb_ball, rb_ball, rmax_b, pad_mm)
        if rows.size == 0:
            continue
        d = np.linalg.norm(pts[rows] - sb.centres_mm[cols], axis=1)
        ok = d <= sa.radii_mm[idx_a[rows]] + sb.radii_mm[cols] + pad_mm
        hit[idx_a[rows[ok]], cols[ok]] = True
    return hit


def _bounding_ball(spheres: SphereSet) -> tuple[FloatArray, float]:
    centre = (spheres.centres_mm.min(axis=0) + spheres.centres_mm.max(axis=0)) / 2.0
    return centre, float(np.max(np.linalg.norm(spheres.centres_mm - centre, axis=1) + spheres.radii_mm))


def _near_nodes(
    tree: JointTree, angles: FloatArray, ja: int, jb: int, sa: SphereSet, sb: SphereSet, pad_mm: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """(G, 4, 4) a's rest frame -> b's rest frame at each grid node, and (G,) where the two parts'
    bounding balls come within ``pad_mm``."""
    ca_ball, ra_ball = _bounding_ball(sa)
    cb_ball, rb_ball = _bounding_ball(sb)
    world = tree.world_of(angles, (ja, jb))
    g = world.shape[0]
    ta = world[:, ja] if ja >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
    tb = world[:, jb] if jb >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
    rel = np.linalg.inv(tb) @ ta
    ball = np.einsum("gij,j->gi", rel, np.r_[ca_ball, 1.0])[:, :3]
    return rel, np.linalg.norm(ball - cb_ball, axis=1) <= ra_ball + rb_ball + pad_mm


def _balls_meet(
    tree: JointTree, angles: FloatArray, ja: int, jb: int, sa: SphereSet, sb: SphereSet, pad_mm: float
) -> bool:
    """Whether the two parts' bounding balls come within ``pad_mm`` at some grid node."""
    per_chunk = 1024  # most pairs that meet do so early in the grid: stop at the first chunk that does
    return any(
        bool(_near_nodes(tree, angles[s : s + per_chunk], ja, jb, sa, sb, pad_mm)[1].any())
        for s in range(0, angles.shape[0], per_chunk)
    )


def _flat(cand: Any) -> tuple[IntArray, IntArray]:
    """(query index, found index) pairs of a ``query_ball_point`` answer (an object array of lists)."""
    lens = np.fromiter(map(len, cand), dtype=np.int64, count=len(cand))
    found = np.fromiter(itertools.chain.from_iterable(cand), dtype=np.int64, count=int(lens.sum()))
    return np.repeat(np.arange(len(cand)), lens), found


def _candidates_from_a(
    pts: FloatArray,
    idx_a: IntArray,
    kd: Any,
    sa: SphereSet,
    sb: SphereSet,
    cb_ball: FloatArray,
    rb_ball: float,
    rmax_b: float,
    pad_mm: float,
) -> tuple[IntArray, IntArray]:
    """Candidate (row of ``pts``, sphere of b) pairs: a's moved centres queried in b's k-d tree, only those
    that reach b's bounding ball (a sphere of a that cannot reach it cannot reach any sphere of b)."""
    reach = np.linalg.norm(pts - cb_ball, axis=1) <= sa.radii_mm[idx_a] + rb_ball + pad_mm + _FILTER_SLACK_MM
    kept = np.flatnonzero(reach)
    cand = kd.query_ball_point(pts[kept], r=sa.radii_mm[idx_a[kept]] + rmax_b + pad_mm, return_sorted=False)
    rows, cols = _flat(cand)
    return kept[rows], cols


def _candidates_from_b(rel: FloatArray, sa: SphereSet, sb: SphereSet, pad_mm: float) -> tuple[IntArray, IntArray]:
    """The same candidates found from b's side (a part much larger than the other): b's centres moved into
    a's rest frame at each node, queried in a's k-d tree; rows index the (node, sphere of a) points."""
    from scipy.spatial import cKDTree

    kd_a = cKDTree(sa.centres_mm)
    q = np.einsum("gij,nj->gni", np.linalg.inv(rel), np.c_[sb.centres_mm, np.ones(sb.n)])[..., :3].reshape(-1, 3)
    idx_b = np.tile(np.arange(sb.n), rel.shape[0])
    r = sb.radii_mm[idx_b] + float(sa.radii_mm.max()) + pad_mm + _FILTER_SLACK_MM
    found_q, found_a = _flat(kd_a.query_ball_point(q, r=r, return_sorted=False))
    node = found_q // sb.n
    return node * sa.n + found_a, idx_b[found_q]


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
