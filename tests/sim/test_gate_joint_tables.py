"""Distance tables over a pair's relative joints and separating-plane proofs (`joint_tables`): a table never
clears a pose where the exact test finds contact (poses right beside contact included), a plane proof's
extents bound every pose's, and the gate's verdicts with them are those without (test_gate_clearance)."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.gate import TwinGate
from servoface.sim.gate import joint_tables as jt
from servoface.sim.gate.clearance import ClearanceSet

from tests.sim.gate_setup import builtin_gate, random_poses


@pytest.fixture(scope="module")
def dog() -> TwinGate:
    return builtin_gate("dog", 1 / 60)


def _pair(gate: TwinGate, a: str, b: str) -> int:
    return next(p for p, s in enumerate(gate.collisions.specs) if (s.a, s.b) == (a, b))


def test_dog_ears_get_their_treatments(dog: TwinGate) -> None:
    col = dog.collisions
    assert _pair(dog, "ear_l", "ear_r") in [p for p, _ in col.plane_proven]
    tabled = {int(p) for p in col.distance.pair_index}
    for side in ("l", "r"):
        assert _pair(dog, "skull", f"ear_{side}") in tabled
    assert builtin_gate("dog", 1 / 60, _no_tables()).collisions.distance.tables == ()


def _no_tables() -> object:
    from servoface.sim.gate import GateConfig

    return GateConfig(clearance=False)


def _near_contact_poses(gate: TwinGate, t: int, rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, J) poses in the cells of grid nodes next to a node in contact (slack <= 0): from a node with
    positive slack towards its neighbour in contact, by up to 0.6 of the step (the table's other joint a
    little off its node; the joints outside the table random)."""
    table = gate.collisions.distance.tables[t]
    counts = [int(c) for c in table.counts]
    slack = np.asarray(table.slack_mm).reshape(counts)
    starts = []
    for k in range(len(counts)):
        lo = [slice(None)] * len(counts)
        hi = [slice(None)] * len(counts)
        lo[k], hi[k] = slice(0, -1), slice(1, None)
        a, b = slack[tuple(lo)], slack[tuple(hi)]
        for idx in np.argwhere((a > 0) & (b <= 0)):
            starts.append((idx.copy(), k, +1))
        for idx in np.argwhere((a <= 0) & (b > 0)):
            i = idx.copy()
            i[k] += 1
            starts.append((i, k, -1))
    assert starts, "no contact in the table's box: nothing near contact to test"
    q = random_poses(gate, n, seed=int(rng.integers(1 << 30)))
    q = np.clip(q, gate.tree.lower_deg, gate.tree.upper_deg)
    joints = [int(j) for j in table.joints]
    for row in range(n):
        idx, k, sign = starts[int(rng.integers(len(starts)))]
        node = table.lower_deg + idx * table.step_deg
        node[k] += sign * table.step_deg[k] * rng.uniform(0.0, 0.6)
        jitter = rng.uniform(-0.05, 0.05, len(joints)) * table.step_deg
        jitter[k] = 0.0
        q[row, joints] = np.clip(node + jitter, table.lower_deg, table.lower_deg + table.step_deg * (table.counts - 1))
    return q


def test_distance_tables_never_clear_contact(dog: TwinGate) -> None:
    """Poses beside contact and random ones (5 % beyond the limits too): where a table clears its pair, the
    exact test finds the meshes apart; enough near-contact poses are cleared for this to mean something."""
    col = dog.collisions
    dist = col.distance
    rng = np.random.default_rng(23)
    cleared_near = 0
    for t, p in enumerate(dist.pair_index):
        spec = col.specs[int(p)]
        near = _near_contact_poses(dog, t, rng, 300)
        q = np.concatenate([near, random_poses(dog, 200, seed=29 + t)])
        world = dog.tree.world(q)
        clear = dist.clear(q)[:, t]
        for k in np.flatnonzero(clear):
            assert not col._collide(spec, world[k]), f"{spec.a}/{spec.b} cleared in contact at {q[k].round(3).tolist()}"
        cleared_near += int(clear[: len(near)].sum())
        assert all(dist.clear_one(t, q[k].tolist()) == clear[k] for k in range(len(q)))
    assert cleared_near > 200, cleared_near


def test_distance_table_slack_bounds_the_exact_distance(dog: TwinGate) -> None:
    """Every node's slack (measured or inherited from the coarse grid) is at most the exact distance there
    minus the margin."""
    col = dog.collisions
    rng = np.random.default_rng(31)
    parts = {p.name: p for p in dog.head.parts}
    for t, p in enumerate(col.distance.pair_index):
        spec = col.specs[int(p)]
        table = col.distance.tables[t]
        ja, jb = parts[spec.a].joint, parts[spec.b].joint
        ia, ib = dog.tree.index[ja], dog.tree.index[jb]
        pick = rng.choice(len(table.slack_mm), size=60, replace=False)
        idx = np.stack(np.unravel_index(pick, tuple(int(c) for c in table.counts)), axis=1)
        q = np.zeros((len(pick), len(dog.tree.names)))
        q[:, table.joints] = table.lower_deg + idx * table.step_deg
        world = dog.tree.world(q)
        na, nb = f"{spec.a}@{spec.tolerance_mm}", f"{spec.b}@{spec.tolerance_mm}"
        for k, node in enumerate(pick):
            d = col.exact.distance(na, nb, world[k, ia], world[k, ib])
            assert table.slack_mm[node] <= d - jt.MARGIN_MM + 1e-9, (spec, node)


def test_plane_extent_bounds_every_pose(dog: TwinGate) -> None:
    """`joint_tables._extent_mm` on a coarse grid bounds the vertices' extent along a normal at random
    poses of the part's own joints (between the grid's nodes too: random normals put extremes there)."""
    tree = dog.tree
    part = next(p for p in dog.head.parts if p.name == "ear_l")
    own = [tree.index["ear_tilt_l"], tree.index["ear_pan_l"]]
    rng = np.random.default_rng(37)
    q = np.zeros((3000, len(tree.names)))
    q[:, own] = rng.uniform(tree.lower_deg[own], tree.upper_deg[own], size=(3000, 2))
    world = tree.world(q)[:, tree.index[part.joint]]
    v = np.c_[np.asarray(part.mesh.vertices), np.ones(len(part.mesh.vertices))]
    for normal in [np.array([1.0, 0.0, 0.0]), *rng.normal(size=(24, 3))]:
        normal = normal / np.linalg.norm(normal)
        lo_bound, hi_bound = jt._extent_mm(tree, part.joint, own, part.mesh, normal, 8.0)
        x = np.einsum("i,gij->gj", normal, world[:, :3, :]) @ v.T
        assert lo_bound <= float(x.min()) and float(x.max()) <= hi_bound, normal
        assert float(x.min()) - lo_bound < 16.0  # and not far off (the allowance, plus what the samples miss)


def test_batched_and_one_pose_flags_agree(dog: TwinGate) -> None:
    """The broad phase's batched and per-pose paths agree with the tables and proofs in place."""
    q = random_poses(dog, 200, seed=41)
    world = dog.tree.world(q)
    batch = dog.collisions.broad.flag(world, q)
    one = np.array([dog.collisions.broad.flag(w, a) for w, a in zip(world, q, strict=True)])
    assert np.array_equal(batch, one)
    assert isinstance(dog.collisions.distance, ClearanceSet)


def test_tabled_pairs_are_flagged_wherever_their_table_does_not_clear(dog: TwinGate) -> None:
    """A pair with sphere tests and a distance table keeps no sphere tests: it is flagged exactly where its
    table does not prove the pose apart (outside the joint box too), so every contact goes to the exact test."""
    col = dog.collisions
    broad = col.broad
    dist = col.distance
    q = random_poses(dog, 400, seed=43)
    world = dog.tree.world(q)
    flags = broad.flag(world, q)
    clear = dist.clear(q)
    tabled = [(t, int(p)) for t, p in enumerate(dist.pair_index) if broad.table_only[int(p)]]
    assert {frozenset((col.specs[p].a, col.specs[p].b)) for _, p in tabled} >= {
        frozenset(("skull", "ear_l")),
        frozenset(("skull", "ear_r")),
    }
    assert broad.n_tests < sum(b.table.n_tests for b in col.built)  # their sphere tests are gone
    contacts = 0
    for t, p in tabled:
        assert np.array_equal(flags[:, p], ~clear[:, t])
        for k in range(len(q)):
            if col._collide(col.specs[p], world[k]):
                contacts += 1
                assert flags[k, p]
    assert contacts > 0
