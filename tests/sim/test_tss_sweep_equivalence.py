"""The TSS build's sweep (pre-filtered k-d queries from either side, early-exit bounding-ball test, shared
sphere covers) gives exactly the tables of the straightforward all-pairs sweep on the same grid."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from servoface.sim.gate.demo_rig import demo_head
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet, cover_spheres
from servoface.sim.gate.tss_build import (
    TssParams,
    _balls_meet,
    _bounding_ball,
    _covered,
    _grid_angles,
    _sweep,
    relative_joints,
)


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
        angles = _grid_angles(tree, rel, lo, hi, np.full(len(rel), 5, dtype=np.int64))
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
            got = _sweep(tree, angles, ja, jb, a_spheres, b_spheres, pad_mm, chunk=5000)
            assert np.array_equal(got, expected)
            ca, ra = _bounding_ball(a_spheres)
            cb, rb = _bounding_ball(b_spheres)
            world = tree.world(angles)
            ta = world[:, ja] if ja >= 0 else np.broadcast_to(np.eye(4), world[:, 0].shape)
            tb = world[:, jb] if jb >= 0 else np.broadcast_to(np.eye(4), world[:, 0].shape)
            ball = np.einsum("gij,j->gi", np.linalg.inv(tb) @ ta, np.r_[ca, 1.0])[:, :3]
            meet = bool(np.any(np.linalg.norm(ball - cb, axis=1) <= ra + rb + pad_mm))
            assert _balls_meet(tree, angles, ja, jb, a_spheres, b_spheres, pad_mm) == meet
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


def _arms(tree: JointTree, part_a: Any, part_b: Any, sa: SphereSet, sb: SphereSet, rel: list[int]) -> np.ndarray:
    from servoface.sim.gate.tss_build import lever_arm_mm

    chain_a = set(tree.chain(part_a.joint))
    return np.array(
        [
            lever_arm_mm(tree, part_a.joint, sa, j) if j in chain_a else lever_arm_mm(tree, part_b.joint, sb, j)
            for j in rel
        ]
    )


def _refined_equals_plain(head: Any, a: str, b: str, spheres: int, fine: int, coarse: int, pad_mm: float) -> bool:
    from servoface.sim.gate.tss_refine import refined_sweep

    tree = JointTree(head.joints)
    parts = {p.name: p for p in head.parts}
    sa, sb = cover_spheres(parts[a].mesh, spheres), cover_spheres(parts[b].mesh, spheres)
    rel = relative_joints(tree, parts[a].joint, parts[b].joint)
    lo, hi = tree.lower_deg[rel], tree.upper_deg[rel]
    counts = np.full(len(rel), fine, dtype=np.int64)
    c_counts = np.full(len(rel), coarse, dtype=np.int64)
    c_step = (hi - lo) / (c_counts - 1)
    c_margin = float(np.sum(_arms(tree, parts[a], parts[b], sa, sb, rel) * np.deg2rad(c_step) / 2.0))
    ja = -1 if parts[a].joint is None else tree.index[parts[a].joint]
    jb = -1 if parts[b].joint is None else tree.index[parts[b].joint]
    plain = _sweep(tree, _grid_angles(tree, rel, lo, hi, counts), ja, jb, sa, sb, pad_mm, 4_000_000)
    refined = refined_sweep(tree, rel, lo, hi, counts, c_counts, c_margin, ja, jb, sa, sb, pad_mm, 4_000_000)
    assert plain.any(), f"{a}/{b}: no pair comes close, the comparison means nothing"
    return bool(np.array_equal(plain, refined))


@pytest.mark.parametrize("pad_mm", [0.0, 0.8, 4.0])
def test_refined_sweep_equals_the_plain_sweep_on_the_demo_rig(pad_mm: float) -> None:
    """The fine sweep seeded from a coarser grid (`tss_refine`) gives the plain fine sweep's hit matrix."""
    head = demo_head()
    for a, b in (("skull", "jaw"), ("skull", "ear_l"), ("eyeball_l", "upper_lid_l")):
        for fine, coarse in ((17, 9), (21, 6)):
            assert _refined_equals_plain(head, a, b, 90, fine, coarse, pad_mm), (a, b, fine, coarse)


def test_refined_sweep_equals_the_plain_sweep_on_the_dog_skull_and_ear() -> None:
    from servoface.sim.heads import load_head

    assert _refined_equals_plain(load_head("dog"), "skull", "ear_l", 160, 41, 21, 0.6)


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
