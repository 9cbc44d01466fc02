"""`SkinTwin.measure_one_faces`' memory of its last keyed answer (the same skinning-joint transforms, offsets
key, static strain and measured subset give it again) equals measuring afresh: on seeded random walks of
both built-in heads with held commands, joint-only and pull-only moves, returns to older commands, other
static values, dtypes and subsets; a caller changing a returned mask changes no later answer; and the gate's
verdicts equal those of a gate that never passes a key (always measures)."""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

import numpy as np
import pytest
from servoface.sim.gate import TwinGate
from servoface.sim.gate.strain import SkinTwin

from tests.sim.gate_setup import builtin_gate

FRAME_PERIOD_S = 1 / 50


@pytest.fixture(scope="module", params=["human", "dog"])
def gate(request: pytest.FixtureRequest) -> TwinGate:
    return builtin_gate(request.param, FRAME_PERIOD_S)


def _walk(gate: TwinGate, n: int, seed: int) -> list[np.ndarray]:
    """Commands: held, joint servos only moved, pull servos only moved, back to an older one, or new."""
    t = gate.table
    rng = np.random.default_rng(seed)
    anchors = np.zeros(t.n, dtype=bool)
    anchors[gate.poser.anchor_cols] = True
    span = (t.max_tick - t.min_tick).astype(np.float64)
    out = [t.neutral_tick.copy()]
    for _ in range(n - 1):
        last = out[-1]
        r = rng.random()
        move = rng.uniform(-0.3, 0.3, t.n) * span
        if r < 0.25:
            goal = last.copy()
        elif r < 0.45:
            goal = last + np.where(anchors, 0.0, move)
        elif r < 0.65:
            goal = last + np.where(anchors, move, 0.0)
        elif r < 0.75 and len(out) > 3:
            goal = out[int(rng.integers(0, len(out)))].copy()
        else:
            goal = last + move
        out.append(np.clip(np.round(goal), t.min_tick, t.max_tick).astype(np.int64))
    return out


def _same(a: tuple[Any, ...], b: tuple[Any, ...]) -> bool:
    return a[:3] == b[:3] and a[3].dtype == b[3].dtype and a[3].tobytes() == b[3].tobytes()


def test_keyed_measure_equals_measuring_afresh(gate: TwinGate) -> None:
    skin, src = gate.skin, gate.skin_source
    rows = skin.fast_vertices
    reused = 0
    for k, goal in enumerate(_walk(gate, 160, seed=5)):
        _, _, world, pulls = gate._pose_arrays(goal[None, :])
        offsets = src.offsets_rows(pulls[0], rows)
        key = src.rows_key(rows)
        assert key is not None
        static = gate._static(goal)
        if k % 7 == 3:  # another static value for the same pose: measured again
            static = (static[0] + 0.5, static[1], static[2] + 1)
        w = world[0].astype(np.float32) if k % 11 == 5 else world[0]  # another dtype: measured again
        before = skin._last_one
        got = skin.measure_one_faces(w, offsets, static, key)
        reused += before is not None and skin._last_one is before  # kept: the memory answered
        fresh = skin.measure_one_faces(w, offsets, static)  # no key: always measured
        assert _same(got, fresh), k
        assert got[3] is not fresh[3]
        got[3][:] = ~got[3]  # the caller's copy: no later answer changes
        assert _same(skin.measure_one_faces(w, offsets, static, key), fresh), k
        assert skin.measure_one(w, offsets, static, key) == fresh[:3]
    assert reused > 10


def test_memory_keeps_subset_static_and_joints_apart(gate: TwinGate) -> None:
    """The same offsets key on another pose of the skinning joints, another static value or another
    measured subset (`measure_only`) is measured again."""
    skin = copy.copy(gate.skin)  # measure_only below replaces the copy's tables, not the gate's
    src = gate.skin_source
    rows = skin.fast_vertices
    goals = _walk(gate, 40, seed=8)
    for goal in goals:
        _, _, world, pulls = gate._pose_arrays(goal[None, :])
        offsets = src.offsets_rows(pulls[0], rows)
        static = gate._static(goal)
        skin.measure_one_faces(world[0], offsets, static, b"one key")
        moved = world[0].copy()
        moved[skin._joints_used[0], 0, 3] += 1.0  # one skinning joint elsewhere
        assert _same(
            skin.measure_one_faces(moved, offsets, static, b"one key"), skin.measure_one_faces(moved, offsets, static)
        )
        other = (static[0], static[1] - 0.25, static[2])
        assert _same(
            skin.measure_one_faces(world[0], offsets, other, b"one key"),
            skin.measure_one_faces(world[0], offsets, other),
        )
    n_e, n_f = len(skin._e0), len(skin._f0)
    rng = np.random.default_rng(2)
    skin.measure_only(rng.random(skin.n_active_edges) < 0.5, rng.random(skin.n_active_faces) < 0.5)
    assert (len(skin._e0), len(skin._f0)) != (n_e, n_f)
    rows = skin.fast_vertices
    goal = goals[-1]
    _, _, world, pulls = gate._pose_arrays(goal[None, :])
    offsets = src.offsets_rows(pulls[0], rows)
    got = skin.measure_one_faces(world[0], offsets, gate._static(goal), b"one key")
    assert _same(got, skin.measure_one_faces(world[0], offsets, gate._static(goal)))


def test_rows_key_names_equal_offsets(gate: TwinGate) -> None:
    """Equal `rows_key`s come with equal offsets (None for rows never asked for)."""
    src = gate.skin_source
    rows = gate.skin.fast_vertices
    assert src.rows_key(np.array(rows)) is None
    by_key: dict[bytes, bytes] = {}
    for goal in _walk(gate, 120, seed=13):
        _, _, _, pulls = gate._pose_arrays(goal[None, :])
        offsets = src.offsets_rows(pulls[0], rows)
        key = src.rows_key(rows)
        assert key is not None
        assert by_key.setdefault(key, offsets.tobytes()) == offsets.tobytes()
    assert len(by_key) > 10


def _verdict(v: Any) -> tuple[Any, ...]:
    return (v.kind, v.goals_tick, [dataclasses.astuple(f) for f in v.findings], v.step_fraction, v.requested_tick)


@pytest.mark.parametrize("name", ["human", "dog"])
def test_gate_verdicts_equal_a_gate_that_always_measures(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Walks of small, clipped, joint-only and pull-only requests from the last verdict: the same verdicts
    and memory as a gate whose skin is never given a key."""
    memo, plain = builtin_gate(name, FRAME_PERIOD_S), builtin_gate(name, FRAME_PERIOD_S)
    skin = plain.skin

    def unkeyed(world: Any, offsets: Any, static: Any = (0.0, np.inf, 0), key: Any = None) -> Any:
        return SkinTwin.measure_one_faces(skin, world, offsets, static)  # the key dropped: always measured

    monkeypatch.setattr(skin, "measure_one_faces", unkeyed)
    t = memo.table
    ids = t.ids
    rng = np.random.default_rng(23)
    anchors = np.zeros(t.n, dtype=bool)
    anchors[memo.poser.anchor_cols] = True
    last = t.neutral_tick.copy()
    for k in range(160):
        r = rng.random()
        size = t.max_step_tick * (3.0 if r < 0.3 else 0.5)
        move = rng.uniform(-1, 1, t.n) * size
        if r < 0.15:
            move[:] = 0.0
        elif r < 0.5:
            move = np.where(anchors, move, 0.0) if k % 2 else np.where(anchors, 0.0, move)
        req = np.clip(last + move, t.min_tick, t.max_tick).astype(np.int64)
        goals = dict(zip(ids, req.tolist(), strict=True))
        prev = dict(zip(ids, last.tolist(), strict=True))
        a, b = memo.check(goals, prev), plain.check(goals, prev)
        assert _verdict(a) == _verdict(b), k
        assert memo.step_state().same(plain.step_state())
        last = np.array([a.goals_tick[i] for i in ids], dtype=np.int64)
