"""The fine TSS sweep seeded from a coarse one: the same table as the plain fine sweep, less work.

A sphere pair (i, j) that comes within ``r_i + r_j + pad`` at a fine grid node also comes within
``r_i + r_j + pad + c_margin`` at the coarse node nearest to it (each joint at most half a coarse step
away; ``c_margin`` bounds how far any sphere moves relative to the other part over that offset, as the
TSS margin does for a fine cell). So a coarse sweep with that larger pad lists, per coarse node, every pair
that can hit at the fine nodes around it, and each fine node only tests those pairs — with the plain
sweep's arithmetic (`tss_build._sweep`: the same transforms, the same distance test on the same points),
so the hit matrix is the plain sweep's. `tests/sim/test_tss_sweep_equivalence.py` compares them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet
from servoface.sim.gate.tss_build import (
    _FILTER_SLACK_MM,
    _bounding_ball,
    _candidates_from_a,
    _candidates_from_b,
    _grid_angles,
    _near_nodes,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
_MAX_TESTS = 2_000_000  # sphere-pair tests per batch (memory)


def pairs_per_node(
    tree: JointTree, angles: FloatArray, ja: int, jb: int, sa: SphereSet, sb: SphereSet, pad_mm: float, chunk: int
) -> tuple[IntArray, IntArray, IntArray]:
    """(node, i, j): every sphere pair within ``r_i + r_j + pad_mm`` at each grid node (as `_sweep` finds them)."""
    from scipy.spatial import cKDTree

    kd = cKDTree(sb.centres_mm)
    ha = np.c_[sa.centres_mm, np.ones(sa.n)]
    rmax_b = float(sb.radii_mm.max())
    cb_ball, rb_ball = _bounding_ball(sb)
    per_chunk = max(1, chunk // max(sa.n, 1))
    nodes, ii, jj = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for start in range(0, angles.shape[0], per_chunk):
        rel, near = _near_nodes(tree, angles[start : start + per_chunk], ja, jb, sa, sb, pad_mm)
        if not near.any():
            continue
        node_ids = start + np.flatnonzero(near)
        pts = np.einsum("gij,nj->gni", rel[near], ha)[..., :3].reshape(-1, 3)
        idx_a = np.tile(np.arange(sa.n), int(near.sum()))
        if sa.n > 2 * sb.n:
            rows, cols = _candidates_from_b(rel[near], sa, sb, pad_mm)
        else:
            rows, cols = _candidates_from_a(pts, idx_a, kd, sa, sb, cb_ball, rb_ball, rmax_b, pad_mm)
        if rows.size == 0:
            continue
        d = np.linalg.norm(pts[rows] - sb.centres_mm[cols], axis=1)
        ok = d <= sa.radii_mm[idx_a[rows]] + sb.radii_mm[cols] + pad_mm
        nodes.append(node_ids[rows[ok] // sa.n])
        ii.append(idx_a[rows[ok]])
        jj.append(cols[ok])
    return np.concatenate(nodes), np.concatenate(ii), np.concatenate(jj)


def refined_sweep(
    tree: JointTree,
    rel: list[int],
    lo: FloatArray,
    hi: FloatArray,
    counts: IntArray,
    c_counts: IntArray,
    c_margin_mm: float,
    ja: int,
    jb: int,
    sa: SphereSet,
    sb: SphereSet,
    pad_mm: float,
    chunk: int,
) -> NDArray[np.bool_]:
    """`tss_build._sweep` over the fine grid ``counts`` (same (n_a, n_b) result), testing at each fine node
    only the pairs the coarse grid ``c_counts`` (same box, in-cell bound ``c_margin_mm``) found near it."""
    hit = np.zeros((sa.n, sb.n), dtype=bool)
    c_pad = pad_mm + c_margin_mm + _FILTER_SLACK_MM
    cn, ci, cj = pairs_per_node(tree, _grid_angles(tree, rel, lo, hi, c_counts), ja, jb, sa, sb, c_pad, chunk)
    if cn.size == 0:
        return hit
    order = np.argsort(cn, kind="stable")
    cn, ci, cj = cn[order], ci[order], cj[order]
    n_coarse = int(np.prod(c_counts))
    first = np.searchsorted(cn, np.arange(n_coarse), side="left")
    count = np.searchsorted(cn, np.arange(n_coarse), side="right") - first
    nearest = []  # per axis: the coarse index nearest each fine index
    for k in range(len(rel)):
        f_ax = np.linspace(lo[k], hi[k], int(counts[k]))
        c_ax = np.linspace(lo[k], hi[k], int(c_counts[k]))
        nearest.append(np.argmin(np.abs(f_ax[:, None] - c_ax[None, :]), axis=1))
    grids = np.meshgrid(*nearest, indexing="ij")
    coarse_of = np.ravel_multi_index(tuple(g.reshape(-1) for g in grids), tuple(int(c) for c in c_counts))
    angles = _grid_angles(tree, rel, lo, hi, counts)
    ha = np.c_[sa.centres_mm, np.ones(sa.n)]
    per_chunk = max(1, chunk // max(sa.n, 1))
    for start in range(0, angles.shape[0], per_chunk):
        rel_t, near = _near_nodes(tree, angles[start : start + per_chunk], ja, jb, sa, sb, pad_mm)
        if not near.any():
            continue
        pts = np.einsum("gij,nj->gni", rel_t[near], ha)[..., :3].reshape(-1, 3)
        m = coarse_of[start + np.flatnonzero(near)]
        cnt = count[m]
        ends = np.cumsum(cnt)
        s = 0
        while s < len(m):  # batches of near nodes holding at most _MAX_TESTS pair tests
            base = ends[s - 1] if s else 0
            e = max(s + 1, int(np.searchsorted(ends, base + _MAX_TESTS, side="right")))
            c = cnt[s:e]
            total = int(c.sum())
            if total:
                rank = np.repeat(np.arange(s, e), c)
                offs = np.repeat(first[m[s:e]] - (np.cumsum(c) - c), c) + np.arange(total)
                i, j = ci[offs], cj[offs]
                rows = rank * sa.n + i
                d = np.linalg.norm(pts[rows] - sb.centres_mm[j], axis=1)
                ok = d <= sa.radii_mm[i] + sb.radii_mm[j] + pad_mm
                hit[i[ok], j[ok]] = True
            s = e
    return hit
