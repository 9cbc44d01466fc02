"""Clearance tables for pairs without a TSS table: never "clear" where the exact test finds contact, and
the gate gives the same verdicts and goals with them as without (the straightforward path)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from servoface.sim.gate import TwinGate
from servoface.sim.gate.clearance import cached_clearance

from tests.sim.gate_setup import random_poses, table_pair


@pytest.fixture(scope="module")
def dog_pair() -> tuple[TwinGate, TwinGate]:
    return table_pair("dog")


def _names(gate: TwinGate) -> dict[frozenset[str], int]:
    col = gate.collisions
    return {frozenset((col.specs[p].a, col.specs[p].b)): t for t, p in enumerate(col.clearance.pair_index)}


def test_dog_always_overlapping_pairs_get_clearance_tables(dog_pair: tuple[TwinGate, TwinGate]) -> None:
    new, old = dog_pair
    cl = new.collisions.clearance
    names = _names(new)
    for side in ("l", "r"):
        for other in (f"eyeball_{side}", f"upper_lid_{side}"):
            assert cl.proven[names[frozenset(("jaw", other))]], f"jaw/{other} not proven apart"
    assert frozenset(("teeth_upper", "tongue_tip")) in names
    assert len(old.collisions.clearance) == 0


def test_clear_never_contradicts_the_exact_test(dog_pair: tuple[TwinGate, TwinGate]) -> None:
    new, old = dog_pair
    col = new.collisions
    q = random_poses(new, 400, seed=5)
    world = new.tree.world(q)
    fresh, plain = col.broad.flag(world, q), old.collisions.broad.flag(world, q)
    # (a pair whose distance table replaces its sphere tests is flagged wherever the table does not clear it,
    # spheres apart or not: test_gate_joint_tables checks those)
    extra = fresh & ~plain & ~col.broad.table_only
    assert not np.any(extra), "the clearance path flagged a pair the plain path did not"
    dropped = 0
    for k, p in zip(*np.nonzero(plain & ~fresh), strict=True):
        dropped += 1
        assert not col._collide(col.specs[p], world[k]), f"cleared {col.specs[p]} at {q[k].round(2).tolist()}"
    assert dropped > 100, "too few cleared pairs to mean anything"
    # the per-pose Python path is the batched arithmetic
    one = np.array([col.broad.flag(w, a) for w, a in zip(world, q, strict=True)])
    assert np.array_equal(one, fresh)
    cl = col.clearance
    batch = cl.clear(q)
    assert all(cl.clear_one(t, q[k].tolist()) == batch[k, t] for k in range(len(q)) for t in range(len(cl)))


@pytest.mark.parametrize("scale", [0.25, 3.0])
def test_gate_gives_the_same_verdicts_and_goals_with_clearance(
    dog_pair: tuple[TwinGate, TwinGate], scale: float
) -> None:
    """A random walk (small steps, or oversized ones that get clipped) through both gates side by side."""
    new, old = dog_pair
    new.reset()
    old.reset()
    t = new.table
    rng = np.random.default_rng(int(scale * 10))
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


def test_clearance_cache_round_trip(dog_pair: tuple[TwinGate, TwinGate], tmp_path: Path) -> None:
    cl = dog_pair[0].collisions.clearance
    table = cl.tables[int(np.flatnonzero(~cl.proven)[0])]
    path = tmp_path / "pair-clear.npz"
    assert cached_clearance(path, lambda: table) is table
    back = cached_clearance(path, lambda: pytest.fail("rebuilt although cached"))
    assert back is not None
    assert back.ball_part == table.ball_part and back.radius_mm == table.radius_mm
    for field in ("centre_mm", "joints", "lower_deg", "step_deg", "counts", "arm_mm", "slack_mm"):
        assert np.array_equal(getattr(back, field), getattr(table, field))
    none_path = tmp_path / "none-clear.npz"
    assert cached_clearance(none_path, lambda: None) is None
    assert cached_clearance(none_path, lambda: pytest.fail("rebuilt although cached")) is None


def test_clearance_lookup_bounds_the_offset_from_the_nearest_node() -> None:
    """A hand-made table: 2 joints, one without range; clear only where the slack beats the offset bound."""
    from servoface.sim.gate.clearance import Clearance, ClearanceSet

    table = Clearance(
        "x",
        np.zeros(3),
        1.0,
        np.array([0, 2], dtype=np.int64),
        np.array([0.0, 5.0]),
        np.array([10.0, 0.0]),  # joint 0: nodes at 0, 10, 20 deg; joint 2: fixed at 5 deg
        np.array([3, 2], dtype=np.int64),
        np.array([10.0, 10.0]),  # mm per rad
        np.array([1.0, 1.0, 0.5, 0.5, 0.0, 0.0]),  # row-major over (joint 0 node, joint 2 node)
    )
    cl = ClearanceSet([0], [table])
    rad = np.pi / 180.0

    def clear(q0: float, q2: float) -> bool:
        q = np.array([q0, 0.0, q2])
        one = cl.clear_one(0, q.tolist())
        assert one == bool(cl.clear(q)[0])
        return one

    assert clear(0.0, 5.0)  # on node (0, 0): slack 1 > 0
    assert clear(4.0, 5.0) == (1.0 > 10.0 * 4.0 * rad)  # nearest node 0: moved 0.70 mm < 1
    assert not clear(6.0, 5.0)  # nearest node 10 deg: slack 0.5 < moved 0.70 mm
    assert not clear(20.0, 5.0)  # slack 0 at the last node
    assert not clear(0.0, 6.0)  # the fixed joint off its only value: outside the table
    assert not clear(-1.0, 5.0) and not clear(21.0, 5.0)  # outside the box
