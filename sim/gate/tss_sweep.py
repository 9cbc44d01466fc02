"""The plain TSS sweep over a grid of joint angles, and the pieces the refined sweep shares with it.

At each grid node a's sphere centres are moved into b's rest frame (inv(T_b) T_a, transforms only along the
two parts' chains); nodes where the two parts' bounding balls stay apart are skipped; candidate sphere
pairs come from a k-d query (made from the side with fewer spheres, skipping spheres that cannot reach the
other part's bounding ball), and a pair is in when its centres are within ``r_i + r_j + pad``.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
FILTER_SLACK_MM = 1e-6  # pre-filters keep a candidate this far beyond their bound (float rounding)


def grid_angles(tree: JointTree, rel: list[int], lo: FloatArray, hi: FloatArray, counts: IntArray) -> FloatArray:
    """(G, J) joint angles of a regular grid over the ``rel`` joints (others at 0)."""
    axes = [np.linspace(lo[i], hi[i], int(counts[i])) for i in range(len(rel))]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(rel)) if rel else np.zeros((1, 0))
    angles = np.zeros((grid.shape[0], len(tree.names)))
    angles[:, rel] = grid
    return angles


def sweep(
    tree: JointTree,
    angles: FloatArray,
    ja: int,
    jb: int,
    sa: SphereSet,
    sb: SphereSet,
    pad_mm: float,
    chunk: int,
) -> NDArray[np.bool_]:
    """(n_a, n_b) True where spheres i of a and j of b come within r_i + r_j + pad at some grid node (the
    plain sweep: every node, the reference the refined sweep of `tss_refine` is checked against)."""
    hit = np.zeros((sa.n, sb.n), dtype=bool)
    for _, i, j in pairs_at_nodes(tree, angles, ja, jb, sa, sb, pad_mm, chunk):
        hit[i, j] = True
    return hit


def pairs_at_nodes(
    tree: JointTree,
    angles: FloatArray,
    ja: int,
    jb: int,
    sa: SphereSet,
    sb: SphereSet,
    pad_mm: float,
    chunk: int,
) -> Iterator[tuple[IntArray, IntArray, IntArray]]:
    """Per chunk of grid nodes: (node, i, j) for every sphere pair within ``r_i + r_j + pad_mm`` at a node
    (node indexes ``angles``).

    Works in b's rest frame (a's centres moved by inv(T_b) T_a), so b's k-d tree is built once; grid
    nodes where the two parts' bounding balls stay apart are skipped.
    """
    from scipy.spatial import cKDTree

    kd = cKDTree(sb.centres_mm)
    ha = np.c_[sa.centres_mm, np.ones(sa.n)]
    rmax_b = float(sb.radii_mm.max())
    cb_ball, rb_ball = bounding_ball(sb)
    per_chunk = max(1, chunk // max(sa.n, 1))
    for start in range(0, angles.shape[0], per_chunk):
        rel, near = near_nodes(tree, angles[start : start + per_chunk], ja, jb, sa, sb, pad_mm)
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
        yield (start + np.flatnonzero(near))[rows[ok] // sa.n], idx_a[rows[ok]], cols[ok]


def bounding_ball(spheres: SphereSet) -> tuple[FloatArray, float]:
    centre = (spheres.centres_mm.min(axis=0) + spheres.centres_mm.max(axis=0)) / 2.0
    return centre, float(np.max(np.linalg.norm(spheres.centres_mm - centre, axis=1) + spheres.radii_mm))


def ball_distance(
    tree: JointTree, angles: FloatArray, ja: int, jb: int, sa: SphereSet, sb: SphereSet
) -> tuple[FloatArray, FloatArray]:
    """(G, 4, 4) a's rest frame -> b's rest frame at each grid node, and (G,) the distance between the
    centres of the two parts' bounding balls there."""
    ca_ball, _ = bounding_ball(sa)
    cb_ball, _ = bounding_ball(sb)
    world = tree.world_of(angles, (ja, jb))
    g = world.shape[0]
    ta = world[:, ja] if ja >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
    tb = world[:, jb] if jb >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
    rel = np.linalg.inv(tb) @ ta
    ball = np.einsum("gij,j->gi", rel, np.r_[ca_ball, 1.0])[:, :3]
    return rel, np.asarray(np.linalg.norm(ball - cb_ball, axis=1), dtype=np.float64)


def near_nodes(
    tree: JointTree, angles: FloatArray, ja: int, jb: int, sa: SphereSet, sb: SphereSet, pad_mm: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """(G, 4, 4) a's rest frame -> b's rest frame at each grid node, and (G,) where the two parts'
    bounding balls come within ``pad_mm``."""
    _, ra_ball = bounding_ball(sa)
    _, rb_ball = bounding_ball(sb)
    rel, dist = ball_distance(tree, angles, ja, jb, sa, sb)
    return rel, dist <= ra_ball + rb_ball + pad_mm


def balls_meet(
    tree: JointTree, angles: FloatArray, ja: int, jb: int, sa: SphereSet, sb: SphereSet, pad_mm: float
) -> bool:
    """Whether the two parts' bounding balls come within ``pad_mm`` at some grid node."""
    per_chunk = 1024  # most pairs that meet do so early in the grid: stop at the first chunk that does
    return any(
        bool(near_nodes(tree, angles[s : s + per_chunk], ja, jb, sa, sb, pad_mm)[1].any())
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
    reach = np.linalg.norm(pts - cb_ball, axis=1) <= sa.radii_mm[idx_a] + rb_ball + pad_mm + FILTER_SLACK_MM
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
    r = sb.radii_mm[idx_b] + float(sa.radii_mm.max()) + pad_mm + FILTER_SLACK_MM
    found_q, found_a = _flat(kd_a.query_ball_point(q, r=r, return_sorted=False))
    node = found_q // sb.n
    return node * sa.n + found_a, idx_b[found_q]
