"""The TSS build's sweep (pre-filtered k-d queries from either side, early-exit bounding-ball test, shared
sphere covers) gives exactly the tables of the straightforward all-pairs sweep on the same grid; the
refined sweep and the pruned bounding-ball test (`tss_refine`) give the plain sweep's answers."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from servoface.sim.gate.demo_rig import demo_head
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet, cover_spheres
from servoface.sim.gate.tss_build import TssParams, _covered, relative_joints
from servoface.sim.gate.tss_sweep import balls_meet, bounding_ball, grid_angles, sweep


def _all_pairs_sweep(
    tree: JointTree, angles: np.ndarray, ja: int, jb: int, sa: SphereSet, sb: SphereSet, pad_mm: float
) -> np.ndarray:
    """Every sphere pair at every grid node (a's centres moved into b's rest frame, as the build does)."""
    world = tree.world(angles)
    g = world.shape[0]
    ta = world[:, ja] if ja >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
    tb = world[:, jb] if jb >= 0 else np.broadcast_to(np.eye(4), (g, 4, 4))
    rel = np.linalg.inv(tb) @ ta
    pts = np.einsum("gij,nj->gni", rel, np.c_[sa.centres_mm, np.ones(sa.n)])[..., :3]
    hit = np.zeros((sa.n, sb.n), dtype=bool)
    for k in range(g):
        d = np.linalg.norm(pts[k][:, None, :] - sb.centres_mm[None, :, :], axis=-1)
        hit |= d <= sa.radii_mm[:, None] + sb.radii_mm[None, :] + pad_mm
    return hit


def _pairs() -> list[tuple[JointTree, int, int, SphereSet, SphereSet, np.ndarray]]:
    head = demo_head()
    tree = JointTree(head.joints)
    parts = {p.name: p for p in head.parts}
    covers = {n: cover_spheres(p.mesh, 90) for n, p in parts.items()}
    out = []
    for a, b in [(x, y) for x in parts for y in parts if x != y]:
        rel = relative_joints(tree, parts[a].joint, parts[b].joint)
        if not rel:
            continue
        lo, hi = tree.lower_deg[rel], tree.upper_deg[rel]
        angles = grid_angles(tree, rel, lo, hi, np.full(len(rel), 5, dtype=np.int64))
        ja = -1 if parts[a].joint is None else tree.index[parts[a].joint]
        jb = -1 if parts[b].joint is None else tree.index[parts[b].joint]
        out.append((tree, ja, jb, covers[a], covers[b], angles))
    return out


@pytest.mark.parametrize("pad_mm", [0.0, 0.8, 4.0])
def test_sweep_equals_the_all_pairs_sweep(pad_mm: float) -> None:
    both_sides = set()
    for tree, ja, jb, sa, sb, angles in _pairs():
        for a_spheres, b_spheres in ((sa, sb), (_halved(sa), sb), (sa, _halved(sb))):
            both_sides.add(a_spheres.n > 2 * b_spheres.n)
            expected = _all_pairs_sweep(tree, angles, ja, jb, a_spheres, b_spheres, pad_mm)
            got = sweep(tree, angles, ja, jb, a_spheres, b_spheres, pad_mm, chunk=5000)
            assert np.array_equal(got, expected)
            ca, ra = bounding_ball(a_spheres)
            cb, rb = bounding_ball(b_spheres)
            world = tree.world(angles)
            ta = world[:, ja] if ja >= 0 else np.broadcast_to(np.eye(4), world[:, 0].shape)
            tb = world[:, jb] if jb >= 0 else np.broadcast_to(np.eye(4), world[:, 0].shape)
            ball = np.einsum("gij,j->gi", np.linalg.inv(tb) @ ta, np.r_[ca, 1.0])[:, :3]
            meet = bool(np.any(np.linalg.norm(ball - cb, axis=1) <= ra + rb + pad_mm))
            assert balls_meet(tree, angles, ja, jb, a_spheres, b_spheres, pad_mm) == meet
    assert both_sides == {True, False}, "both query directions must be exercised"


def _halved(spheres: SphereSet) -> SphereSet:
    keep = np.arange(0, spheres.n, 5)
    return SphereSet(spheres.centres_mm[keep], spheres.radii_mm[keep])


def test_a_shared_cover_is_the_cover_of_that_mesh() -> None:
    """A part in many pairs is covered once per build: what the shared dict hands back is what
    `cover_spheres` gives for that very mesh (it is deterministic), never another mesh's."""
    params = TssParams()
    covers: dict[int, tuple[object, SphereSet]] = {}
    parts = demo_head().parts
    for part in parts:
        fresh = cover_spheres(part.mesh, params.spheres_per_part, max_cell_mm=params.max_cell_mm)
        first = _covered(part.mesh, params, covers)
        assert _covered(part.mesh, params, covers) is first
        assert np.array_equal(first.centres_mm, fresh.centres_mm) and np.array_equal(first.radii_mm, fresh.radii_mm)
    other = parts[0].mesh.copy()
    stale = covers[id(parts[1].mesh)][1]
    covers[id(other)] = (parts[1].mesh, stale)  # an entry under this id for another mesh (a reused id)
    got = _covered(other, params, covers)
    assert got is not stale and np.array_equal(got.centres_mm, covers[id(parts[0].mesh)][1].centres_mm)


def _refined_equals_plain(
    head: Any, a: str, b: str, spheres: int, fine: Any, pad_mm: float, box: tuple[float, float] = (0.0, 1.0)
) -> bool:
    """`refined_sweep` against the plain `sweep` on ``fine`` nodes per axis over the share ``box`` of each
    joint's range (the pyramid's levels and reach follow from the grid)."""
    from servoface.sim.gate.tss_build import pair_sphere_arms
    from servoface.sim.gate.tss_refine import refined_sweep

    tree = JointTree(head.joints)
    parts = {p.name: p for p in head.parts}
    sa, sb = cover_spheres(parts[a].mesh, spheres), cover_spheres(parts[b].mesh, spheres)
    rel = relative_joints(tree, parts[a].joint, parts[b].joint)
    span = tree.upper_deg[rel] - tree.lower_deg[rel]
    lo, hi = tree.lower_deg[rel] + box[0] * span, tree.lower_deg[rel] + box[1] * span
    counts = np.resize(np.asarray(fine, dtype=np.int64), len(rel))
    arms = pair_sphere_arms(tree, parts[a].joint, parts[b].joint, sa, sb, rel)
    ja = -1 if parts[a].joint is None else tree.index[parts[a].joint]
    jb = -1 if parts[b].joint is None else tree.index[parts[b].joint]
    plain = sweep(tree, grid_angles(tree, rel, lo, hi, counts), ja, jb, sa, sb, pad_mm, 4_000_000)
    refined = refined_sweep(tree, rel, lo, hi, counts, arms, ja, jb, sa, sb, pad_mm, 4_000_000)
    assert plain.any(), f"{a}/{b}: no pair comes close, the comparison means nothing"
    return bool(np.array_equal(plain, refined))


@pytest.mark.parametrize("pad_mm", [0.0, 0.8, 4.0])
def test_refined_sweep_equals_the_plain_sweep_on_the_demo_rig(pad_mm: float) -> None:
    """The fine sweep seeded from coarser grids (`tss_refine`) gives the plain fine sweep's hit matrix."""
    head = demo_head()
    for a, b in (("skull", "jaw"), ("skull", "ear_l"), ("eyeball_l", "upper_lid_l")):
        for fine in (17, 40, (90, 13)):
            assert _refined_equals_plain(head, a, b, 90, fine, pad_mm), (a, b, fine)


def test_refined_sweep_equals_the_plain_sweep_on_random_boxes() -> None:
    """Random sub-boxes of the joint ranges, grid sizes and pads on the demo rig and the dog."""
    from servoface.sim.heads import load_head

    rng = np.random.default_rng(11)
    heads = {"demo": demo_head(), "dog": load_head("dog")}
    cases = [
        ("demo", "skull", "jaw"),
        ("demo", "skull", "ear_l"),
        ("dog", "skull", "ear_l"),
        ("dog", "jaw", "teeth_upper"),
    ]
    compared = 0
    for _ in range(4):
        for name, a, b in cases:
            start = float(rng.uniform(0.0, 0.5))
            box = (start, float(min(1.0, start + rng.uniform(0.3, 0.8))))
            fine = rng.integers(9, 70, size=2)
            pad = float(rng.uniform(0.0, 3.0))
            try:
                assert _refined_equals_plain(heads[name], a, b, 120, fine, pad, box), (name, a, b, box, fine, pad)
                compared += 1
            except AssertionError as err:
                if "means nothing" not in str(err):
                    raise
    assert compared >= 10, "too few random cases had any pair close"


def test_refined_sweep_equals_the_plain_sweep_on_the_dog_skull_and_ear() -> None:
    from servoface.sim.heads import load_head

    assert _refined_equals_plain(load_head("dog"), "skull", "ear_l", 160, (105, 99), 0.88)


def test_pruned_balls_meet_gives_the_plain_answer() -> None:
    """`pruned_balls_meet` (ball centres placed per sub-grid of each part, the plain test only where they
    are close) answers as the plain test on pairs of the demo rig and the dog, at pads just above and
    below the closest approach over the grid (where a filter that cut too much would flip the answer)
    and a random one."""
    from servoface.sim.gate.tss_refine import pruned_balls_meet
    from servoface.sim.gate.tss_sweep import ball_distance
    from servoface.sim.heads import load_head

    rng = np.random.default_rng(5)
    answers = []
    for head in (demo_head(), load_head("dog")):
        tree = JointTree(head.joints)
        parts = {p.name: p for p in head.parts}
        covers = {n: cover_spheres(p.mesh, 40) for n, p in parts.items()}
        names = sorted(parts)
        pairs = [
            (x, y) for x in names for y in names if x < y and relative_joints(tree, parts[x].joint, parts[y].joint)
        ]
        for k in rng.choice(len(pairs), size=min(24, len(pairs)), replace=False):
            a, b = pairs[int(k)]
            rel = relative_joints(tree, parts[a].joint, parts[b].joint)
            lo, hi = tree.lower_deg[rel], tree.upper_deg[rel]
            counts = np.full(len(rel), max(2, int(round(1800 ** (1 / len(rel))))), dtype=np.int64)
            counts += rng.integers(0, 3, size=len(rel))
            ja = -1 if parts[a].joint is None else tree.index[parts[a].joint]
            jb = -1 if parts[b].joint is None else tree.index[parts[b].joint]
            sa, sb = covers[a], covers[b]
            angles = grid_angles(tree, rel, lo, hi, counts)
            gap = ball_distance(tree, angles, ja, jb, sa, sb)[1] - bounding_ball(sa)[1] - bounding_ball(sb)[1]
            closest = float(gap.min())
            for pad in (closest + 1e-9, closest - 1e-9, float(rng.uniform(-20.0, 30.0))):
                plain = balls_meet(tree, angles, ja, jb, sa, sb, pad)
                got = pruned_balls_meet(tree, rel, lo, hi, counts, parts[a].joint, sa, sb, ja, jb, pad)
                assert got == plain, (a, b, counts, pad, closest, int(np.argmin(gap)))
                answers.append(plain)
    assert any(answers) and not all(answers)


def test_every_fine_node_lies_within_reach_of_its_ancestors() -> None:
    """The pyramid's reach per level bounds the angle between each fine node and its ancestor there."""
    from servoface.sim.gate.tss_refine import grid_pyramid

    rng = np.random.default_rng(3)
    for _ in range(20):
        n = int(rng.integers(1, 4))
        lo = rng.uniform(-60, 0, n)
        hi = lo + rng.uniform(1, 90, n)
        counts = rng.integers(2, 80, n)
        levels = grid_pyramid(lo, hi, counts, top_nodes=int(rng.integers(1, 100)))
        fine = levels[0]
        node = np.arange(fine.n_nodes)
        angle = np.stack(np.unravel_index(node, fine.counts))
        fine_deg = np.array([fine.axes_deg[k][angle[k]] for k in range(n)])
        for k in range(1, len(levels)):
            node = levels[k - 1].up[node]
            idx = np.unravel_index(node, levels[k].counts)
            anc_deg = np.array([levels[k].axes_deg[a][idx[a]] for a in range(n)])
            assert np.all(np.abs(fine_deg - anc_deg) <= levels[k].reach_deg[:, None] + 1e-12)
            assert levels[k].n_nodes < levels[k - 1].n_nodes


@pytest.mark.parametrize("name", ["demo", "dog"])
def test_world_of_two_chains_is_worlds_arithmetic(name: str) -> None:
    """The TSS build's transforms along two parts' chains only are bit-identical to the full `world`."""
    from servoface.sim.heads import load_head

    tree = JointTree((demo_head() if name == "demo" else load_head(name)).joints)
    q = np.random.default_rng(4).uniform(tree.lower_deg, tree.upper_deg, size=(300, len(tree.names)))
    full = tree.world(q)
    for ja in range(-1, len(tree.names)):
        for jb in (-1, 0, len(tree.names) - 1):
            part = tree.world_of(q, (ja, jb))
            for j in {ja, jb} - {-1}:
                assert np.array_equal(part[:, j], full[:, j]), (ja, jb, j)


@pytest.mark.parametrize(
    ("params", "kinds_expected"),
    [
        (TssParams(spheres_per_part=80), {"table True True", "table False True"}),
        (TssParams(spheres_per_part=140, margin_mm=1.2), {"table True True", "table False True"}),
        (TssParams(spheres_per_part=60, max_margin_mm=0.7, max_grid_points=3000), {"coarse True", "coarse False"}),
    ],
)
def test_build_pair_equals_the_plain_build_on_the_demo_rig(params: TssParams, kinds_expected: set[str]) -> None:
    """Every pair of the demo rig: the built table (refined sweep, pruned bounding-ball test) is the plain
    sweep's on the same grid, and a pair too coarse for a table is exact-only exactly when the plain
    bounding-ball test says its balls meet."""
    from servoface.sim.gate.tss_build import build_pair, pair_lever_arms, sweep_grid

    head = demo_head()
    tree = JointTree(head.joints)
    parts = {p.name: p for p in head.parts}
    covers: dict[int, tuple[object, SphereSet]] = {}
    kinds = set()
    for a, b in [(x, y) for x in sorted(parts) for y in sorted(parts) if x < y]:
        rel = relative_joints(tree, parts[a].joint, parts[b].joint)
        if not rel:
            continue
        sa, sb = _covered(parts[a].mesh, params, covers), _covered(parts[b].mesh, params, covers)
        table = build_pair(tree, parts[a], parts[b], sa, sb, 0.0, params, "k")
        lo, hi = tree.lower_deg[rel], tree.upper_deg[rel]
        counts, _, margin = sweep_grid(
            lo, hi, pair_lever_arms(tree, parts[a].joint, parts[b].joint, sa, sb, rel), params
        )
        angles = grid_angles(tree, rel, lo, hi, counts)
        ja = -1 if parts[a].joint is None else tree.index[parts[a].joint]
        jb = -1 if parts[b].joint is None else tree.index[parts[b].joint]
        if margin > params.max_margin_mm:
            assert table.exact_only == balls_meet(tree, angles, ja, jb, sa, sb, margin), (a, b)
            assert table.n_tests == 0
            kinds.add(f"coarse {table.exact_only}")
        else:
            ia, ib = np.nonzero(sweep(tree, angles, ja, jb, sa, sb, margin, params.chunk_elements))
            assert np.array_equal(table.ia, ia) and np.array_equal(table.ib, ib), (a, b)
            kinds.add(f"table {len(ia) > 0} {len(angles) > 64}")
    assert kinds_expected <= kinds, kinds
