"""Pieces of the gate's per-frame path that compute the same numbers more cheaply, compared bit for bit with
the straightforward computation on random inputs (both built-in heads)."""

from __future__ import annotations

import dataclasses

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
