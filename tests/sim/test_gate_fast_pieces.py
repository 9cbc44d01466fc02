"""Pieces of the gate's per-frame path that compute the same numbers more cheaply, compared bit for bit with
the straightforward computation on random inputs (both built-in heads)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from servoface.sim.gate import TwinGate


def _gate(name: str) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(name)
    assert head.calibration_path is not None
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60)


@pytest.fixture(scope="module", params=["human", "dog"])
def gate(request: pytest.FixtureRequest) -> TwinGate:
    return _gate(request.param)


def test_field_rows_equal_the_whole_field_gathered(gate: TwinGate) -> None:
    """`SkinSource.offsets_rows` with the field computed on the rows only (sparse rows + sphincter caps)
    equals the whole field's rows, bit for bit, for random pulls and random contractions (sphincters
    contracted both ways, past their caps too)."""
    src = gate.skin_source
    assert src.field_rows is not None and src.field is not None
    rows = gate.skin.fast_vertices
    plain = dataclasses.replace(src, field_rows=None, _rows={})
    rng = np.random.default_rng(11)
    span = src.upper_mm - src.lower_mm
    pulls = rng.uniform(src.lower_mm - 0.1 * span, src.upper_mm + 0.1 * span, size=(40, len(span)))
    for p in pulls:
        assert np.array_equal(src.offsets_rows(p, rows), plain.offsets_rows(p, rows))
    n_muscles = src.unit_pull.shape[1]
    sub = rng.choice(gate.skin.active_vertices, size=min(300, len(gate.skin.active_vertices)), replace=False)
    sub = np.sort(sub).astype(np.int64)
    for _ in range(40):
        c = rng.uniform(-0.5, 3.0, n_muscles) * (rng.random(n_muscles) < 0.6)
        assert np.array_equal(src.field_rows(c, sub), src.field(c)[sub])
        assert np.array_equal(src.field_rows(c, rows), src.field(c)[rows])


def test_world_one_equals_the_batched_transforms(gate: TwinGate) -> None:
    """`JointTree.world_one` (the per-frame check's single pose) equals `world` on a batch of one, bit for
    bit, on random angles inside and beyond the joint limits."""
    tree = gate.tree
    rng = np.random.default_rng(3)
    span = tree.upper_deg - tree.lower_deg
    q = rng.uniform(tree.lower_deg - 0.2 * span - 5, tree.upper_deg + 0.2 * span + 5, size=(300, len(tree.names)))
    batched = tree.world(q)
    for k in range(len(q)):
        assert np.array_equal(tree.world_one(q[k]), tree.world(q[k][None])[0])
        assert np.array_equal(tree.world_one(q[k]), batched[k])


def test_world_filled_in_parts_equals_world_one(gate: TwinGate) -> None:
    """A pose's transforms filled in two parts (`JointTree.fill_one`: some joints' ancestry first, as the
    clip search does for the pairs a request collided on, then the rest) equal `world_one`'s and the
    batch's, bit for bit; the first part alone already holds its joints' numbers."""
    tree = gate.tree
    rng = np.random.default_rng(7)
    span = tree.upper_deg - tree.lower_deg
    q = rng.uniform(tree.lower_deg - 0.2 * span, tree.upper_deg + 0.2 * span, size=(100, len(tree.names)))
    batched = tree.world(q)
    for k in range(len(q)):
        picked = rng.choice(len(tree.names), size=int(rng.integers(1, 4)), replace=False)
        first = tree.ancestry(int(j) for j in picked)
        rest = [i for i in range(len(tree.names)) if i not in set(first)]
        loc = tree.local_one(q[k])
        out = np.full_like(loc, np.nan)
        tree.fill_one(out, loc, first)
        assert np.array_equal(out[first], batched[k][first])
        tree.fill_one(out, loc, rest)
        assert np.array_equal(out, tree.world_one(q[k])) and np.array_equal(out, batched[k])


@dataclasses.dataclass(frozen=True)
class _Joint:
    name: str
    parent: str | None
    pivot_mm: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower_deg: float = -90.0
    upper_deg: float = 90.0


def test_world_by_levels_equals_joint_by_joint() -> None:
    """`JointTree.fill_levels` (a tree level per stacked product, on ints, slices or index arrays) equals
    `fill_one` joint by joint, bit for bit, on random trees (several roots, levels whose joints or parents are
    not consecutive, shared and distinct parents) and random angles."""
    from servoface.sim.gate.fk import JointTree

    rng = np.random.default_rng(17)
    kinds = set()
    for _ in range(60):
        n = int(rng.integers(1, 14))
        parents = [None if j == 0 or rng.random() < 0.15 else int(rng.integers(0, j)) for j in range(n)]
        order = rng.permutation(n)  # listed in any order: the tree sorts them parent first
        joints = [
            _Joint(
                f"j{j}",
                None if parents[j] is None else f"j{parents[j]}",
                tuple(rng.uniform(-50, 50, 3)),
                tuple(rng.uniform(-1, 1, 3) + 0.01),
            )
            for j in order
        ]
        tree = JointTree(joints)
        kinds |= {type(i).__name__ for level in tree._levels for i in level if i is not None}
        for q in rng.uniform(-120, 120, size=(5, n)):
            loc = tree.local_one(q)
            plain = np.full_like(loc, np.nan)
            tree.fill_one(plain, loc, range(n))
            levels = np.full_like(loc, np.nan)
            tree.fill_levels(levels, loc)
            assert np.array_equal(levels, plain)
            assert np.array_equal(tree.world_one(q), plain)
    assert kinds == {"int", "slice", "ndarray"}  # every kind of index was exercised


def test_goal_vector_fast_path_equals_the_checked_path(gate: TwinGate) -> None:
    """The fast path of `TwinGate._vector` (every servo, table order, plain ints) gives what the checked
    path gives on random goal maps, well-formed and malformed (bool / numpy / float keys and values, huge
    ints, missing, extra and reordered servos)."""
    t = gate.table
    rng = np.random.default_rng(5)
    base = t.neutral_tick.copy()
    odd_values = [True, 1.5, float("nan"), np.int64(7), 2**62, -(2**62), 2**63 + 5, "12", None]
    for trial in range(400):
        values: list[object] = [int(v) for v in rng.integers(t.min_tick, t.max_tick + 1)]
        keys: list[object] = list(t.ids)
        kind = trial % 8
        if kind == 1:
            values[int(rng.integers(t.n))] = odd_values[int(rng.integers(len(odd_values)))]
        elif kind == 2:
            keys[0] = True if keys[0] == 1 else np.int64(keys[0])
        elif kind == 3:
            keys, values = keys[::-1], values[::-1]
        elif kind == 4:
            keys, values = keys[:-1], values[:-1]
        elif kind == 5:
            keys[-1] = max(t.ids) + 1
        elif kind == 6:
            keys[1] = float(keys[1])
        goals = dict(zip(keys, values, strict=True))
        for use_base in (None, base):
            try:
                fast = gate._vector(goals, use_base, "goals_tick")
            except OverflowError:
                with pytest.raises(OverflowError):
                    gate._vector_checked(goals, use_base, "goals_tick")
                continue
            slow = gate._vector_checked(goals, use_base, "goals_tick")
            assert np.array_equal(fast[0], slow[0]) and fast[0].dtype == slow[0].dtype
            assert [(f.check, f.message) for f in fast[1]] == [(f.check, f.message) for f in slow[1]]


def _measure_one_gathers(skin: Any, world: np.ndarray, offsets: np.ndarray, static: tuple[float, float, int]) -> Any:
    """`SkinTwin.measure_one` written plainly: the same float32 steps with the corners gathered by index."""
    mats = skin._mats(world).astype(np.float32)
    m = mats.T @ skin._fw_t32
    o = offsets.T.astype(np.float32)
    rv = skin._frest_vt32
    x, y, z = rv[0] + o[0], rv[1] + o[1], rv[2] + o[2]
    p = [((m[4 * r] * x + m[4 * r + 1] * y) + m[4 * r + 2] * z) + m[4 * r + 3] for r in range(3)]
    d = [c[skin._e0] - c[skin._e1] for c in p]
    r2 = ((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2]) * skin._fe_inv
    r = mats.T @ skin._ffw_t32
    n0, n1, n2 = skin._fn32
    e = [(r[4 * k] * n0 + r[4 * k + 1] * n1) + r[4 * k + 2] * n2 for k in range(3)]
    u = [c[skin._f1] - c[skin._f0] for c in p]
    w = [c[skin._f2] - c[skin._f0] for c in p]
    cx = (u[1] * w[2] - u[2] * w[1]) * e[0]
    cy = (u[2] * w[0] - u[0] * w[2]) * e[1]
    cz = (u[0] * w[1] - u[1] * w[0]) * e[2]
    dot = (cx + cy) + cz
    hi2 = max(float(r2.max()), static[0]) if r2.size else static[0]
    lo2 = min(float(r2.min()), static[1]) if r2.size else static[1]
    stretch = max(float(np.sqrt(hi2)), skin._const_max)
    comp = min(float(np.sqrt(lo2)), skin._const_min)
    return stretch, comp, int(np.count_nonzero(dot <= 0.0)) + skin._const_flips + static[2]


def test_measure_one_equals_the_plain_gathers(gate: TwinGate) -> None:
    """The per-frame strain measure (in place, gathers by `take`) equals the plain gather-and-subtract
    arithmetic exactly, on random commands anywhere in the limits."""
    t = gate.table
    rng = np.random.default_rng(13)
    rows = gate.skin.fast_vertices
    for _ in range(60):
        goal = rng.integers(t.min_tick, t.max_tick + 1).astype(np.int64)
        _, _, world, pulls = gate._pose_arrays(goal[None, :])
        offsets = gate.skin_source.offsets_rows(pulls[0], rows)
        static = gate._static(goal)
        assert gate.skin.measure_one(world[0], offsets, static) == _measure_one_gathers(
            gate.skin, world[0], offsets, static
        )


def test_one_pose_broad_phase_equals_the_plain_gathers(gate: TwinGate) -> None:
    """The one-pose TSS broad phase (gathers by `take`) flags exactly the pairs the plain fancy-index
    distances flag, on random poses."""
    broad = gate.collisions.broad
    tree = gate.tree
    rng = np.random.default_rng(17)
    q = rng.uniform(tree.lower_deg, tree.upper_deg, size=(80, len(tree.names)))
    for k in range(len(q)):
        world = tree.world_one(q[k])
        cx, cy, cz = np.ascontiguousarray(broad.centres(world).T)
        ga, gb = broad.ga, broad.gb
        d2 = (cx[ga] - cx[gb]) ** 2 + (cy[ga] - cy[gb]) ** 2 + (cz[ga] - cz[gb]) ** 2
        want = np.zeros(broad.n_pairs, dtype=bool)
        if broad.n_tests:
            want[broad._nonempty] = np.logical_or.reduceat(d2 <= broad.thr2, broad._starts)
        assert np.array_equal(broad._overlaps_flat(world), want)


def test_offsets_rows_reuse_equals_computing_afresh(gate: TwinGate) -> None:
    """`SkinSource.offsets_rows` gives its last answer again only for the same clipped pulls and fitted
    contractions on the same rows: on a sequence with held, returned-to, clipped-alike and new pulls over
    two row sets, every answer equals a source without that memory (a replaced copy each call), and a
    caller changing a returned array changes no later answer."""
    src = gate.skin_source
    rows_a = gate.skin.fast_vertices
    rows_b = np.ascontiguousarray(rows_a[::3])
    rng = np.random.default_rng(19)
    span = src.upper_mm - src.lower_mm
    seen: list[np.ndarray] = []
    reused = 0
    for k in range(120):
        r = rng.random()
        if seen and r < 0.3:
            p = seen[-1].copy()  # held
        elif len(seen) > 2 and r < 0.45:
            p = seen[int(rng.integers(0, len(seen)))].copy()  # back to an older one
        elif seen and r < 0.55:
            p = seen[-1] + np.where(rng.random(len(span)) < 0.5, 50.0, 0.0) * span  # differs only beyond the clip
        else:
            p = rng.uniform(src.lower_mm - 0.1 * span, src.upper_mm + 0.1 * span)
        seen.append(p)
        rows = rows_a if k % 5 else rows_b
        before = src._last.get(id(rows))
        got = src.offsets_rows(p, rows)
        reused += before is not None and before is src._last.get(id(rows))  # kept: the memory answered
        fresh = dataclasses.replace(src, _rows={}).offsets_rows(p, rows)
        assert got.tobytes() == fresh.tobytes(), k
        got += 1.0  # the caller's copy
    assert reused > 20


def test_one_command_pose_equals_the_batch_path(gate: TwinGate) -> None:
    """`TwinPoser.pose_one` (targets, joint angles, pulls of one command) and the gate's shares with their
    divisors kept equal the batch path's (`targets`, `joint_angles`, `pulls`, `coupling.travel_share`) bit for
    bit, on random commands inside and beyond the tick limits; `_pose_arrays` of one row equals its rows of
    a batch."""
    from servoface.sim.gate.coupling import travel_share

    p = gate.poser
    t = gate.table
    rng = np.random.default_rng(17)
    span = t.max_tick - t.min_tick
    goals = rng.integers(t.min_tick - span // 10, t.max_tick + span // 10 + 1, size=(300, t.n)).astype(np.int64)
    batch = gate._pose_arrays(goals)
    for k, goal in enumerate(goals):
        target, angle, pull = p.pose_one(goal)
        targets = p.targets(goal[None, :])
        assert np.array_equal(target, targets[0])
        assert np.array_equal(angle, p.joint_angles(targets)[0])
        assert np.array_equal(pull, p.pulls(targets)[0])
        shares = travel_share(targets, p.target_lower, p.target_upper, p.target_neutral)
        assert np.array_equal(gate._shares(targets), shares)
        one = gate._pose_arrays(goal[None, :])
        for got, want in zip(one, batch, strict=True):
            assert got.shape[0] == 1 and np.array_equal(got[0], want[k])


def test_one_pose_skinning_transforms_equal_the_batched_gather(gate: TwinGate) -> None:
    """`SkinTwin._mats` of one pose (gathered from the joints' transforms when the head base carries no
    skin) equals the batched gather with the base's identity appended, bit for bit, on random poses."""
    skin = gate.skin
    rng = np.random.default_rng(23)
    tree = gate.tree
    q = rng.uniform(tree.lower_deg - 5, tree.upper_deg + 5, size=(100, len(tree.names)))
    world = tree.world(q)
    for k in range(len(q)):
        full = np.concatenate([world[k], np.eye(4)[None]], axis=0)[skin._used, :3, :].reshape(len(skin._used), 12)
        assert np.array_equal(skin._mats(world[k]), full)
        assert np.array_equal(skin._mats(world[k][None])[0], full)
