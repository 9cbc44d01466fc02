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
