"""The fine TSS sweep seeded from coarser grids: the same answers as the plain fine sweep, less work.

A pyramid of grids spans the pair's joint box, each level about half as fine per axis as the one below,
up to a top grid of at most ``_TOP_NODES`` nodes. Each node's parent is the nearest node per axis of the
next coarser level, so every fine node f has one ancestor per level. A sphere pair (i, j) within
``r_i + r_j + pad`` at f is within ``r_i + r_j + pad + reach_k`` at its level-k ancestor, where ``reach_k`` =
sum over joints of the lever arm times the largest angle between a fine node and its level-k ancestor
(how far either sphere can move relative to the other over that offset, as the TSS margin bounds a
cell). So a k-d sweep of the top grid with that pad lists every pair that can hit below each top node;
each level tests at each node only the pairs its parent listed, with its own reach; and the fine level
tests them with the plain sweep's arithmetic (the same transforms, the same distance test on the same
points), so the hit matrix is the plain sweep's (`tss_sweep.sweep`). A pair already found is not tested
again. Whether two parts' bounding balls meet at any node (`pruned_balls_meet`, for pairs too coarse for a
table) is decided on the grid as the product of the two parts' sub-grids. `tests/sim/
test_tss_sweep_equivalence.py` compares both with the plain versions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet
from servoface.sim.gate.tss_sweep import (
    FILTER_SLACK_MM,
    bounding_ball,
    grid_angles,
    near_nodes,
    pairs_at_nodes,
    sweep,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
_TOP_NODES = 64  # the top grid's k-d sweep: small enough that its large pad stays cheap
_MAX_TESTS = 1_000_000  # sphere-pair tests per batch (memory)
_FINE_TESTS = 20_000  # on the fine level: small batches, so pairs found are not tested again at later nodes
_NODES_PER_BATCH = 4096  # nodes whose transforms are computed together
_FIRST_NODES = 32  # `pruned_balls_meet` runs the plain test on this many closest nodes first,
_CHUNK_NODES = 1024  # then on the others this many at a time


@dataclass
class GridLevel:
    """One grid of the pyramid over the box [lo, hi]."""

    axes_deg: list[FloatArray]  # per axis: the node angles (np.linspace over the box, as `grid_angles`)
    reach_deg: FloatArray  # per axis: largest angle between a fine node and its ancestor on this grid
    up: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))  # (nodes,) each node's parent one
    # level coarser (flat index); empty on the top level

    @property
    def counts(self) -> tuple[int, ...]:
        return tuple(len(a) for a in self.axes_deg)

    @property
    def n_nodes(self) -> int:
        return int(np.prod(self.counts))

    def angles(self, tree: JointTree, rel: Sequence[int], nodes: IntArray) -> FloatArray:
        """(len(nodes), J) joint angles of these nodes (flat row-major indices), others at 0: the values
        `grid_angles` gives the same nodes."""
        out = np.zeros((len(nodes), len(tree.names)))
        for k, idx in enumerate(np.unravel_index(nodes, self.counts)):
            out[:, rel[k]] = self.axes_deg[k][idx]
        return out


def grid_pyramid(lo: FloatArray, hi: FloatArray, counts: IntArray, top_nodes: int = _TOP_NODES) -> list[GridLevel]:
    """levels[0] is the fine grid ``counts`` itself; each next level has max(2, ceil(n / 2)) nodes per axis."""
    axes = [np.linspace(lo[k], hi[k], int(counts[k])) for k in range(len(counts))]
    anc = [np.arange(len(a)) for a in axes]  # per axis: fine index -> its ancestor's index on the current level
    levels = [GridLevel(axes, np.zeros(len(axes)))]
    while levels[-1].n_nodes > top_nodes and any(c > 2 for c in levels[-1].counts):
        cur = levels[-1]
        nxt = [np.linspace(lo[k], hi[k], max(2, -(-len(a) // 2))) for k, a in enumerate(cur.axes_deg)]
        near = [np.argmin(np.abs(a[:, None] - b[None, :]), axis=1) for a, b in zip(cur.axes_deg, nxt, strict=True)]
        grids = np.meshgrid(*near, indexing="ij")
        cur.up = np.ravel_multi_index(tuple(g.reshape(-1) for g in grids), tuple(len(b) for b in nxt)).astype(np.int64)
        anc = [n[a] for n, a in zip(near, anc, strict=True)]
        reach = np.array([np.max(np.abs(f - b[a])) for f, b, a in zip(axes, nxt, anc, strict=True)])
        levels.append(GridLevel(nxt, reach))
    return levels


def refined_sweep(
    tree: JointTree,
    rel: list[int],
    lo: FloatArray,
    hi: FloatArray,
    counts: IntArray,
    arms_mm: tuple[FloatArray, FloatArray],
    ja: int,
    jb: int,
    sa: SphereSet,
    sb: SphereSet,
    pad_mm: float,
    chunk: int,
) -> BoolArray:
    """`tss_sweep.sweep` over the fine grid ``counts`` (the same (n_a, n_b) result), seeded from the
    pyramid above it. ``arms_mm``: (n_a, R) and (n_b, R), per sphere and ``rel`` joint, how fast (mm per
    rad) the joint moves that sphere (`tss_build.sphere_arms_mm`; 0 for a joint of the other part's chain)."""
    levels = grid_pyramid(lo, hi, counts)
    hit = np.zeros((sa.n, sb.n), dtype=bool)
    if len(levels) == 1:
        return sweep(tree, grid_angles(tree, rel, lo, hi, counts), ja, jb, sa, sb, pad_mm, chunk)
    top = levels[-1]
    ta, tb = _inflated(sa, arms_mm[0], top), _inflated(sb, arms_mm[1], top)
    found = list(
        pairs_at_nodes(
            tree, top.angles(tree, rel, np.arange(top.n_nodes)), ja, jb, ta, tb, pad_mm + FILTER_SLACK_MM, chunk
        )
    )
    nodes, ii, jj = (np.concatenate([np.zeros(0, np.int64), *(f[k] for f in found)]) for k in range(3))
    for k in range(len(levels) - 2, -1, -1):
        if k:
            la, lb = _inflated(sa, arms_mm[0], levels[k]), _inflated(sb, arms_mm[1], levels[k])
            radii, pad = (la.radii_mm, lb.radii_mm), pad_mm + FILTER_SLACK_MM
            ball_pad = pad + float(np.max(la.radii_mm - sa.radii_mm)) + float(np.max(lb.radii_mm - sb.radii_mm))
        else:  # the fine level: the plain sweep's test
            radii, pad, ball_pad = (sa.radii_mm, sb.radii_mm), pad_mm, pad_mm
        nodes, ii, jj = _descend(
            tree,
            rel,
            levels[k],
            levels[k + 1].n_nodes,
            (nodes, ii, jj),
            ja,
            jb,
            sa,
            sb,
            radii,
            pad,
            ball_pad,
            hit if k == 0 else None,
        )
        if nodes.size == 0 and k > 0:
            break
    return hit


def _inflated(spheres: SphereSet, arms_mm: FloatArray, level: GridLevel) -> SphereSet:
    """The spheres grown by how far each can move between a fine node and its ancestor on ``level``."""
    grow = arms_mm @ np.deg2rad(level.reach_deg) if arms_mm.size else np.zeros(spheres.n)
    return SphereSet(spheres.centres_mm, spheres.radii_mm + grow + FILTER_SLACK_MM)


def _descend(
    tree: JointTree,
    rel: list[int],
    level: GridLevel,
    n_parents: int,
    listed: tuple[IntArray, IntArray, IntArray],
    ja: int,
    jb: int,
    sa: SphereSet,
    sb: SphereSet,
    radii_mm: tuple[FloatArray, FloatArray],
    pad_mm: float,
    ball_pad_mm: float,
    hit: BoolArray | None,
) -> tuple[IntArray, IntArray, IntArray]:
    """Test at each node of ``level`` the pairs ``listed`` (parent node, i, j) for its parent: those within
    ``radii_a[i] + radii_b[j] + pad_mm`` come back as (node, i, j), or on the fine level (``hit`` given)
    are marked in ``hit`` (pairs already marked are not tested again). Nodes whose bounding balls stay
    ``ball_pad_mm`` apart are skipped."""
    order = np.argsort(listed[0], kind="stable")
    nodes, ii, jj = (x[order] for x in listed)
    first = np.searchsorted(nodes, np.arange(n_parents), side="left")
    count = np.searchsorted(nodes, np.arange(n_parents), side="right") - first
    kids = np.flatnonzero(count[level.up] > 0)
    ha = np.c_[sa.centres_mm, np.ones(sa.n)]
    rad_a, rad_b = radii_mm
    batch = _MAX_TESTS if hit is None else _FINE_TESTS
    out: list[tuple[IntArray, IntArray, IntArray]] = [(np.zeros(0, np.int64),) * 3]
    for start in range(0, len(kids), _NODES_PER_BATCH):
        kid = kids[start : start + _NODES_PER_BATCH]
        rel_t, near = near_nodes(tree, level.angles(tree, rel, kid), ja, jb, sa, sb, ball_pad_mm)
        kid, rel_n = kid[near], rel_t[near]
        m = level.up[kid]
        cnt = count[m]
        ends = np.cumsum(cnt)
        s = 0
        while s < len(m):  # batches of nodes holding at most `batch` pair tests
            base = ends[s - 1] if s else 0
            e = max(s + 1, int(np.searchsorted(ends, base + batch, side="right")))
            c = cnt[s:e]
            total = int(c.sum())
            rank = np.repeat(np.arange(s, e), c)
            offs = np.repeat(first[m[s:e]] - (np.cumsum(c) - c), c) + np.arange(total)
            i, j = ii[offs], jj[offs]
            if hit is not None:
                fresh = ~hit[i, j]
                rank, i, j = rank[fresh], i[fresh], j[fresh]
            diff = _moved(rel_n, ha, s, e, rank, i) - sb.centres_mm[j]
            if hit is not None:  # the plain sweep's distance test
                ok = np.linalg.norm(diff, axis=1) <= rad_a[i] + rad_b[j] + pad_mm
                hit[i[ok], j[ok]] = True
            else:  # squared: the bound carries FILTER_SLACK_MM, far above the rounding this changes
                ok = np.einsum("ki,ki->k", diff, diff) <= np.square(rad_a[i] + rad_b[j] + pad_mm)
                out.append((kid[rank[ok]], i[ok], j[ok]))
            s = e
    return tuple(np.concatenate([o[k] for o in out]) for k in range(3))  # type: ignore[return-value]


def _moved(rel_n: FloatArray, ha: FloatArray, s: int, e: int, rank: IntArray, i: IntArray) -> FloatArray:
    """(len(i), 3) a's centres ``i`` moved by ``rel_n[rank]`` (rank in [s, e)), with the plain sweep's
    einsum (bit for bit: each point is the same sum over the same transform row and centre): as a table over
    the nodes s..e and the spheres named, when that is smaller than one point per test, else per test."""
    named = np.zeros(ha.shape[0], dtype=bool)
    named[i] = True
    used = np.flatnonzero(named)
    if (e - s) * len(used) <= len(i):
        table = np.einsum("gij,nj->gni", rel_n[s:e], ha[used])[..., :3]
        return np.asarray(table[rank - s, (np.cumsum(named) - 1)[i]], dtype=np.float64)
    return np.asarray(np.einsum("kij,kj->ki", np.ascontiguousarray(rel_n[:, :3, :])[rank], ha[i]), dtype=np.float64)


def pruned_balls_meet(
    tree: JointTree,
    rel: list[int],
    lo: FloatArray,
    hi: FloatArray,
    counts: IntArray,
    joint_a: str | None,
    sa: SphereSet,
    sb: SphereSet,
    ja: int,
    jb: int,
    pad_mm: float,
) -> bool:
    """`tss_sweep.balls_meet` over the fine grid ``counts`` (the same answer). ``rel`` splits into the joints
    of a's chain and those of b's (every other joint is at 0 on the grid), so the grid is the product of
    the two sub-grids: each ball's centre is placed in the world once per node of its part's sub-grid, the
    centres' distance at every node is one subtraction, and only nodes within the pad (plus float slack:
    the plain test works in b's frame) go to the plain test."""
    fine = GridLevel([np.linspace(lo[k], hi[k], int(counts[k])) for k in range(len(rel))], np.zeros(len(rel)))
    chain_a = set(tree.chain(joint_a))
    side_a = [k for k, j in enumerate(rel) if j in chain_a]
    side_b = [k for k, j in enumerate(rel) if j not in chain_a]
    ca, ra = bounding_ball(sa)
    cb, rb = bounding_ball(sb)
    idx = np.unravel_index(np.arange(fine.n_nodes), fine.counts)
    at_a = _placed(tree, rel, fine, side_a, ja, ca)[_sub_index(idx, fine.counts, side_a)]
    at_b = _placed(tree, rel, fine, side_b, jb, cb)[_sub_index(idx, fine.counts, side_b)]
    dist = np.linalg.norm(at_a - at_b, axis=1)
    close = np.flatnonzero(dist <= ra + rb + pad_mm + FILTER_SLACK_MM)
    close = close[np.argsort(dist[close], kind="stable")]  # nearest first: a pair that meets stops early
    starts = [0, *range(_FIRST_NODES, max(len(close), _FIRST_NODES), _CHUNK_NODES)]
    return any(
        bool(near_nodes(tree, fine.angles(tree, rel, close[s:e]), ja, jb, sa, sb, pad_mm)[1].any())
        for s, e in zip(starts, [*starts[1:], len(close)], strict=True)
        if e > s
    )


def _sub_index(idx: tuple[IntArray, ...], counts: tuple[int, ...], side: list[int]) -> IntArray:
    """Each fine node's flat index in the sub-grid of the axes ``side``."""
    if not side:
        return np.zeros(len(idx[0]) if idx else 1, dtype=np.int64)
    return np.asarray(np.ravel_multi_index(tuple(idx[k] for k in side), tuple(counts[k] for k in side)), np.int64)


def _placed(
    tree: JointTree, rel: list[int], fine: GridLevel, side: list[int], joint: int, centre: FloatArray
) -> FloatArray:
    """(sub-grid nodes, 3) world position of a point fixed to ``joint`` (-1: the head base) at each node of
    the sub-grid over the axes ``side`` (row-major in ``rel`` order, which runs root first along the chain).
    Built joint by joint from the part's own joint up: each joint's transform per angle applied to the
    positions so far, a new slowest axis each time (joints of the chain outside ``side`` are at 0)."""
    pts = np.asarray(centre, dtype=np.float64)[None, :]
    if joint < 0 or not side:
        return pts
    angles_of = {rel[k]: fine.axes_deg[k] for k in side}
    for j in tree.chain(tree.names[joint]):
        if j not in angles_of:
            continue
        local = tree.local(angles_of[j][:, None], [j])[:, 0]  # (n, 4, 4)
        moved = np.einsum("aij,mj->ami", local[:, :3, :3], pts) + local[:, None, :3, 3]
        pts = moved.reshape(-1, 3)
    return pts
