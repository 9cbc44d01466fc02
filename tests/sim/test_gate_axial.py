"""Axial distance tables (pairs turning about one line, the lid pairs): never "clear" where the exact test
finds contact, the bound they rest on holds between nodes, and the gate gives the same verdicts and goals
with them as without (the straightforward path)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from servoface.sim.gate import TwinGate
from servoface.sim.gate.axial import AxialSet, AxialTable, build_axial, cached_axial
from servoface.sim.gate.tss_build import relative_joints

from tests.sim.gate_setup import random_poses, table_pair


@pytest.fixture(scope="module")
def human_pair() -> tuple[TwinGate, TwinGate]:
    return table_pair("human")


def _tables(gate: TwinGate) -> dict[frozenset[str], int]:
    col = gate.collisions
    return {frozenset((col.specs[p].a, col.specs[p].b)): t for t, p in enumerate(col.axial.pair_index)}


def test_human_lid_pairs_get_axial_tables(human_pair: tuple[TwinGate, TwinGate]) -> None:
    new, old = human_pair
    names = _tables(new)
    for side in ("l", "r"):
        assert frozenset((f"upper_lid_{side}", f"lower_lid_{side}")) in names
    assert len(old.collisions.axial) == 0
    # the eyeballs turn about two axes each: their relative joints are not on one line
    assert frozenset(("eyeball_l", "eyeball_r")) not in names


def test_axial_clear_never_contradicts_the_exact_test(human_pair: tuple[TwinGate, TwinGate]) -> None:
    new, old = human_pair
    col = new.collisions
    q = random_poses(new, 400, seed=11)
    # half the poses with the lids closing onto each other (the closest the shells come)
    names = _tables(new)
    lids = [(new.tree.index[f"upper_lid_{s}"], new.tree.index[f"lower_lid_{s}"]) for s in ("l", "r")]
    rng = np.random.default_rng(12)
    for ju, jl in lids:
        q[::2, ju] = rng.uniform(40.0, 58.0, size=len(q[::2]))
        q[::2, jl] = rng.uniform(15.0, 27.0, size=len(q[::2]))
    world = new.tree.world(q)
    fresh, plain = col.broad.flag(world, q), old.collisions.broad.flag(world, q)
    assert not np.any(fresh & ~plain), "the axial path flagged a pair the plain path did not"
    dropped = {t: 0 for t in names.values()}
    for k, p in zip(*np.nonzero(plain & ~fresh), strict=True):
        assert not col._collide(col.specs[p], world[k]), f"cleared {col.specs[p]} at {q[k].round(2).tolist()}"
        t = int(np.flatnonzero(col.axial.pair_index == p)[0])
        dropped[t] += 1
    for side in ("l", "r"):
        assert dropped[names[frozenset((f"upper_lid_{side}", f"lower_lid_{side}"))]] > 100
    # the per-pose Python path is the batched arithmetic
    one = np.array([col.broad.flag(w, a) for w, a in zip(world, q, strict=True)])
    assert np.array_equal(one, fresh)
    ax = col.axial
    batch = ax.clear(q)
    assert all(ax.clear_one(t, q[k].tolist()) == batch[k, t] for k in range(len(q)) for t in range(len(ax)))


def test_axial_bound_holds_between_nodes(human_pair: tuple[TwinGate, TwinGate]) -> None:
    """The distance at any s is at least the nearest node's slack minus the arm times the offset, and the
    relative transform is the one at s alone (beyond the joint limits too)."""
    new, _ = human_pair
    col, tree = new.collisions, new.tree
    rng = np.random.default_rng(13)
    for t, p in enumerate(col.axial.pair_index):
        spec, table = col.specs[int(p)], col.axial.tables[t]

        def pose(world: np.ndarray, part: str) -> np.ndarray:
            j = col.part_joint[part]
            return (
                np.broadcast_to(np.eye(4), (*world.shape[:-3], 4, 4)) if j is None else world[..., tree.index[j], :, :]
            )

        q = random_poses(new, 40, seed=14 + t)
        s = q[:, table.joints] @ table.coef
        alone = np.zeros_like(q)
        alone[:, table.joints[0]] = s * table.coef[0]
        wq, ws = tree.world(q), tree.world(alone)
        rel_q = np.linalg.inv(pose(wq, spec.a)) @ pose(wq, spec.b)
        rel_s = np.linalg.inv(pose(ws, spec.a)) @ pose(ws, spec.b)
        assert np.allclose(rel_q, rel_s, rtol=0.0, atol=1e-7)
        n = len(table.slack_mm)
        for x in rng.uniform(table.lower_deg, table.lower_deg + (n - 1) * table.step_deg, size=12):
            i = int(np.rint((x - table.lower_deg) / table.step_deg))
            bound = table.slack_mm[i] - np.deg2rad(table.arm_mm) * abs(x - (table.lower_deg + i * table.step_deg))
            w = tree.world(np.eye(len(tree.names))[table.joints[0]][None] * (x * table.coef[0]))[0]
            na, nb = f"{spec.a}@{spec.tolerance_mm}", f"{spec.b}@{spec.tolerance_mm}"
            assert col.exact.distance(na, nb, pose(w, spec.a), pose(w, spec.b)) >= bound, (spec, x)


def test_no_axial_table_off_one_line(human_pair: tuple[TwinGate, TwinGate]) -> None:
    new, _ = human_pair
    tree = new.tree

    def never(_a: np.ndarray, _b: np.ndarray) -> float:
        raise AssertionError("distances asked for although the joints are not on one line")

    ja, jb = "eye_tilt_l", "eye_tilt_r"
    assert build_axial(tree, ja, jb, relative_joints(tree, ja, jb), None, None, never) is None


@pytest.mark.parametrize("scale", [0.25, 3.0])
def test_gate_gives_the_same_verdicts_and_goals_with_axial_tables(
    human_pair: tuple[TwinGate, TwinGate], scale: float
) -> None:
    """A random walk (small steps, or oversized ones that get clipped) through both gates side by side."""
    new, old = human_pair
    new.reset()
    old.reset()
    t = new.table
    rng = np.random.default_rng(int(scale * 10) + 1)
    last = new.neutral_goals()
    kinds = set()
    for _ in range(80):
        base = np.array([last[i] for i in t.ids])
        req = np.clip(base + rng.uniform(-1, 1, t.n) * t.max_step_tick * scale, t.min_tick, t.max_tick)
        goals = {int(i): int(v) for i, v in zip(t.ids, req.astype(np.int64), strict=True)}
        a = new.check(goals, last)
        b = old.check(goals, last)
        assert (a.kind, a.goals_tick, a.step_fraction) == (b.kind, b.goals_tick, b.step_fraction)
        assert [(f.check, f.message) for f in a.findings] == [(f.check, f.message) for f in b.findings]
        kinds.add(a.kind)
        last = a.goals_tick
    assert ("accept" if scale < 1 else "clip") in kinds, kinds


def test_axial_cache_round_trip(human_pair: tuple[TwinGate, TwinGate], tmp_path: Path) -> None:
    table = human_pair[0].collisions.axial.tables[0]
    path = tmp_path / "pair-axial.npz"
    assert cached_axial(path, lambda: table) is table
    back = cached_axial(path, lambda: pytest.fail("rebuilt although cached"))
    assert back is not None
    assert (back.lower_deg, back.step_deg, back.arm_mm) == (table.lower_deg, table.step_deg, table.arm_mm)
    for field in ("joints", "coef", "slack_mm"):
        assert np.array_equal(getattr(back, field), getattr(table, field))
    none_path = tmp_path / "none-axial.npz"
    assert cached_axial(none_path, lambda: None) is None
    assert cached_axial(none_path, lambda: pytest.fail("rebuilt although cached")) is None


def test_axial_lookup_bounds_the_offset_from_the_nearest_node() -> None:
    """A hand-made table over s = q0 - q2: clear only where the slack beats the offset bound."""
    table = AxialTable(
        np.array([0, 2], dtype=np.int64),
        np.array([1.0, -1.0]),
        0.0,
        10.0,  # nodes at s = 0, 10, 20 deg
        10.0,  # mm per rad
        np.array([1.0, 0.5, 0.0]),
    )
    ax = AxialSet([0], [table])
    rad = np.pi / 180.0

    def clear(q0: float, q2: float) -> bool:
        q = np.array([q0, 0.0, q2])
        one = ax.clear_one(0, q.tolist())
        assert one == bool(ax.clear(q)[0])
        assert one == bool(ax.clear(q[None])[0, 0])
        return one

    assert clear(0.0, 0.0) and clear(7.0, 7.0)  # on node 0: slack 1 > 0
    assert clear(4.0, 0.0) == (1.0 > 10.0 * 4.0 * rad)  # nearest node 0: moved 0.70 mm < 1
    assert clear(9.0, 5.0)  # s = 4: the same
    assert not clear(6.0, 0.0)  # nearest node 10 deg: slack 0.5 < moved 0.70 mm
    assert clear(10.0, 0.0) and clear(12.0, 2.0)  # on node 10: slack 0.5 > 0
    assert not clear(20.0, 0.0)  # slack 0 at the last node
    assert not clear(-1.0, 0.0) and not clear(21.0, 0.0) and not clear(0.0, 1.0)  # outside the grid


def test_axial_table_where_the_pair_does_touch(human_pair: tuple[TwinGate, TwinGate]) -> None:
    """The lower lid grown about the eye centre until the shells cross: the table must leave the poses in
    contact to the exact test (and still clear the ones with the lids apart)."""
    import trimesh
    from servoface.sim.gate.exact import ExactCollider

    new, _ = human_pair
    tree, col = new.tree, new.collisions
    upper, lower = (col._meshes[f"{n}_lid_l@0.0"] for n in ("upper", "lower"))
    c = tree.pivot_mm[tree.index["upper_lid_l"]]
    grown = trimesh.Trimesh(c + (np.asarray(lower.vertices) - c) * 1.03, np.asarray(lower.faces), process=False)
    exact = ExactCollider({"u": upper, "l": grown})
    rel = relative_joints(tree, "upper_lid_l", "lower_lid_l")
    table = build_axial(
        tree, "upper_lid_l", "lower_lid_l", rel, upper, grown, lambda a, b: exact.distance("u", "l", a, b)
    )
    assert table is not None
    ax = AxialSet([0], [table])
    q = random_poses(new, 300, seed=21)
    world = tree.world(q)
    ju, jl = tree.index["upper_lid_l"], tree.index["lower_lid_l"]
    hit = np.array([exact.collide("u", "l", w[ju], w[jl]) for w in world])
    cleared = ax.clear(q)[:, 0]
    assert hit.sum() > 20 and cleared.sum() > 20, (hit.sum(), cleared.sum())
    assert not np.any(cleared & hit), "cleared a pose in contact"
    assert np.array_equal(cleared, [ax.clear_one(0, p.tolist()) for p in q])
