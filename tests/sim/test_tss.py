"""Tabulated Sphere Subsets: covering spheres, no missed collisions over a dense sweep, reduction, cache."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from servoface.sim.gate.collision import PartCollisions, auto_pairs
from servoface.sim.gate.demo_rig import demo_head
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import cover_spheres
from servoface.sim.gate.tss_build import TssParams, build_or_load, summed_reduction


@pytest.fixture(scope="module")
def demo_collisions(tmp_path_factory: pytest.TempPathFactory) -> PartCollisions:
    head = demo_head()
    tree = JointTree(head.joints)
    return PartCollisions(head, tree, auto_pairs(head, tree), TssParams(), tmp_path_factory.getbasetemp() / "tss-demo")


@pytest.mark.parametrize(
    "mesh",
    [
        trimesh.creation.icosphere(3, radius=12.0),
        trimesh.creation.box((80, 8, 30)),
        trimesh.creation.cylinder(radius=3.0, height=60.0),
    ],
)
def test_spheres_cover_every_surface_point(mesh: trimesh.Trimesh) -> None:
    spheres = cover_spheres(mesh, target_count=60)
    pts = np.vstack([mesh.vertices, trimesh.sample.sample_surface(mesh, 3000, seed=1)[0]])
    d = np.linalg.norm(pts[:, None, :] - spheres.centres_mm[None, :, :], axis=-1) - spheres.radii_mm
    assert np.all(d.min(axis=1) <= 1e-9), "a surface point lies outside every sphere"
    assert 20 <= spheres.n <= 400


def test_dense_sweep_misses_no_exact_collision(demo_collisions: PartCollisions) -> None:
    col = demo_collisions
    tree = col.tree
    rng = np.random.default_rng(7)
    checked = 0
    for spec, built in zip(col.specs, col.built, strict=True):
        idx = [tree.index[j] for j in built.table.joints]
        lo, hi = tree.lower_deg[idx], tree.upper_deg[idx]
        # a dense grid 3x finer than the build's (off its nodes), plus random poses, over this pair's joints
        fine = [
            np.linspace(a, b, max(2, int(round((b - a) / max(s, 1e-9))) * 3 + 1))
            for a, b, s in zip(lo, hi, built.table.step_deg, strict=True)
        ]
        grid = np.stack(np.meshgrid(*fine, indexing="ij"), -1).reshape(-1, len(idx))
        if len(grid) > 600:
            grid = grid[rng.choice(len(grid), 600, replace=False)]
        grid = np.vstack([grid, rng.uniform(lo, hi, size=(150, len(idx)))])
        q = np.tile(tree.neutral_deg, (len(grid), 1))
        q[:, idx] = grid
        world = tree.world(q)
        flags = col.broad.flag(world, q)[:, col.specs.index(spec)]
        exact = np.array([col._collide(spec, w) for w in world])
        assert not np.any(exact & ~flags), f"TSS missed a collision of {spec.a}/{spec.b}"
        checked += int(exact.sum())
    assert checked > 100, "the sweep found too few collisions to mean anything"


def test_tss_tests_at_least_95_percent_fewer_sphere_pairs(demo_collisions: PartCollisions) -> None:
    tables = [b.table for b in demo_collisions.built]
    assert summed_reduction(tables) >= 0.95
    assert demo_collisions.n_tests < 0.05 * demo_collisions.n_all_sphere_pairs
    # the jaw/skull pair alone (the thesis' showcase) too
    jaw = next(b.table for b in demo_collisions.built if {b.table.a, b.table.b} == {"skull", "jaw"})
    assert jaw.reduction >= 0.95 and jaw.n_tests > 0


def test_out_of_swept_box_flags_the_pair(demo_collisions: PartCollisions) -> None:
    tree = demo_collisions.tree
    q = tree.neutral_deg.copy()[None, :]
    q[0, tree.index["jaw"]] = 40.0  # beyond the jaw's range, where the table is not valid
    out = demo_collisions.broad.out_of_box(q)[0]
    names = [(s.a, s.b) for s, o in zip(demo_collisions.specs, out, strict=True) if o]
    assert ("skull", "jaw") in names and ("ear_l", "eyeball_l") not in names


def test_cache_reused_and_rebuilt_when_a_mesh_changes(tmp_path: Path) -> None:
    head = demo_head()
    tree = JointTree(head.joints)
    skull, jaw = head.parts[0], head.parts[1]
    params = TssParams(spheres_per_part=60)
    first = build_or_load(tree, "demo", skull, jaw, skull.mesh, jaw.mesh, 0.0, params, tmp_path)
    again = build_or_load(tree, "demo", skull, jaw, skull.mesh, jaw.mesh, 0.0, params, tmp_path)
    assert not first.from_cache and again.from_cache
    assert np.array_equal(first.table.ia, again.table.ia) and again.table.key == first.table.key
    moved = jaw.mesh.copy()
    moved.apply_translation((0.0, -3.0, 0.0))
    rebuilt = build_or_load(tree, "demo", skull, jaw, skull.mesh, moved, 0.0, params, tmp_path)
    assert not rebuilt.from_cache and rebuilt.table.key != first.table.key
    assert len(list(tmp_path.glob("demo-skull-jaw-*.npz"))) == 2
    # joint limits are part of the key as well
    wider = JointTree(
        [j if j.name != "jaw" else type(j)(j.name, j.parent, j.pivot_mm, j.axis, -12.0, 25.0) for j in head.joints]
    )
    assert (
        build_or_load(wider, "demo", skull, jaw, skull.mesh, jaw.mesh, 0.0, params, tmp_path).table.key
        != first.table.key
    )


def test_corrupt_cache_file_is_a_clear_error(tmp_path: Path) -> None:
    from servoface.sim.gate.errors import TssCacheError
    from servoface.sim.gate.tss_build import pair_key

    head = demo_head()
    tree = JointTree(head.joints)
    skull, jaw = head.parts[0], head.parts[1]
    params = TssParams(spheres_per_part=40)
    key = pair_key(tree, skull, jaw, skull.mesh, jaw.mesh, 0.0, params)
    (tmp_path / f"demo-skull-jaw-{key}.npz").write_bytes(b"not an npz")
    with pytest.raises(TssCacheError, match="demo-skull-jaw"):
        build_or_load(tree, "demo", skull, jaw, skull.mesh, jaw.mesh, 0.0, params, tmp_path)
