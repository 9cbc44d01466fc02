"""The gate's per-frame fast path (active-skin float32 strain, memo of the last command, batched broad
phase in the scale-back) gives the same verdicts as the slow reference path (`TwinGate.audit`: full skin,
exact test on every pair) on random commands and AU frames, for both built-in heads."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate


def _gate(name: str) -> tuple[TwinGate, Any]:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head

    head = load_head(name)
    fm = FaceModel(head)
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig(), face_model=fm), fm


@pytest.fixture(scope="module", params=["human", "dog"])
def gate_fm(request: pytest.FixtureRequest) -> tuple[TwinGate, Any]:
    return _gate(request.param)


def _state_kinds(findings: list[Any]) -> list[tuple[str, tuple[str, ...] | None]]:
    return sorted((f.check, f.parts) for f in findings if f.check != "limit")


def _commands(gate: TwinGate, fm: Any, n: int, seed: int) -> np.ndarray:
    """Random commands within the limits (near neutral and anywhere) plus AU frames through the face
    model, as (n, servos) ticks."""
    t = gate.table
    rng = np.random.default_rng(seed)
    wide = rng.integers(t.min_tick, t.max_tick + 1, size=(n // 3, t.n))
    span = (t.max_tick - t.min_tick) * rng.uniform(0.05, 0.4, size=(n // 3, 1))
    near = np.clip(t.neutral_tick + rng.uniform(-1, 1, (n // 3, t.n)) * span, t.min_tick, t.max_tick)
    cal = gate.poser.calibration
    names = list(fm.au_names)
    aus_rows = []
    for _ in range(n - 2 * (n // 3)):
        picked = rng.choice(names, size=rng.integers(1, 6), replace=False)
        aus = {}
        for k in picked:
            lo, hi = fm.au_range(k)
            aus[str(k)] = float(rng.uniform(lo, hi))
        goals = cal.targets_to_goals(fm.solve(aus).actuator_targets)
        aus_rows.append([goals[i] for i in t.ids])
    return np.vstack([wide, near.astype(np.int64), np.array(aus_rows, dtype=np.int64)]).astype(np.int64)


def test_fast_state_checks_match_the_audit(gate_fm: tuple[TwinGate, Any]) -> None:
    gate, fm = gate_fm
    t = gate.table
    cmds = _commands(gate, fm, 240, seed=5)
    kinds_seen = set()
    for row in cmds:
        goals = dict(zip(t.ids, row.tolist(), strict=True))
        fast = gate._hard_findings(row)
        slow = gate.audit(goals)
        assert _state_kinds(fast) == _state_kinds(slow), goals
        kinds_seen |= {f.check for f in slow}
        # the numbers agree too: float32 fast strain vs the full reference measure
        _, _, world, pulls = gate._pose_arrays(row[None, :])
        s_ref, c_ref, f_ref = gate.skin.measure(world[0], gate.skin_source.offsets(pulls[0]))
        rows = gate.skin.fast_vertices
        offsets = gate.skin_source.offsets_rows(pulls[0], rows)
        s, c, f = gate.skin.measure_one(world[0], offsets, gate._static(row))
        assert f == int(f_ref)
        lim = gate.config.strain
        if gate.skin_proven == (0, 0):
            assert s == pytest.approx(float(s_ref), rel=1e-4) and c == pytest.approx(float(c_ref), rel=1e-4)
        else:  # skin proven inside the limits is not measured: the numbers agree where they decide
            assert s <= float(s_ref) * (1 + 1e-4) and c >= float(c_ref) * (1 - 1e-4)
            if float(s_ref) > lim.max_stretch:
                assert s == pytest.approx(float(s_ref), rel=1e-4)
            if float(c_ref) < lim.min_compression:
                assert c == pytest.approx(float(c_ref), rel=1e-4)
    assert kinds_seen & {"collision", "coupling", "strain", "flip"}, "no state check ever fired"


def test_human_jaw_skin_is_tabulated_per_jaw_tick() -> None:
    """The human's joint-only skin (skull/jaw blend) is tabulated over the jaw servo's ticks; each entry
    equals measuring that skin at the tick."""
    gate, _ = _gate("human")
    st = gate.static_skin
    assert st is not None and gate.poser.roles[st.column] == "jaw"
    static_e, static_f = gate.skin.split_static()
    assert static_e.any() and static_f.any()
    for tick in (int(gate.table.min_tick[st.column]), int(gate.table.max_tick[st.column])):
        goal = gate.table.neutral_tick.copy()
        goal[st.column] = tick
        _, _, world, _ = gate._pose_arrays(goal[None, :])
        hi2, lo2, flips = gate.skin.measure_static(world, static_e, static_f)
        assert st.values(goal) == pytest.approx((float(hi2[0]), float(lo2[0]), int(flips[0])), rel=1e-9)


def test_scale_back_picks_the_last_candidate_the_audit_passes(gate_fm: tuple[TwinGate, Any]) -> None:
    gate, fm = gate_fm
    t = gate.table
    cmds = _commands(gate, fm, 60, seed=9)
    for a, b in zip(cmds[:-1], cmds[1:], strict=True):
        fracs = np.arange(1, 9) / 8.0
        cands = (a + np.trunc(fracs[:, None] * (b - a)[None, :])).astype(np.int64)
        ok = [
            not [f for f in gate.audit(dict(zip(t.ids, c.tolist(), strict=True))) if f.check != "limit"] for c in cands
        ]
        expected = max((k for k, good in enumerate(ok) if good), default=None)
        assert gate._last_ok(cands) == expected
        # with the pairs the request (b) collides on tested first, as `check` passes them
        hit = {f.parts for f in gate._hard_findings(b) if f.check == "collision"}
        suspects = tuple(p for p, s in enumerate(gate.collisions.specs) if (s.a, s.b) in hit)
        assert gate._last_ok(cands, suspects) == expected


def test_verdicts_of_a_walk_match_a_fresh_gate_without_memo(gate_fm: tuple[TwinGate, Any]) -> None:
    """Holding a command (same request again) reuses the memo: same verdict as a gate checking afresh."""
    gate, fm = gate_fm
    t = gate.table
    fresh, _ = _gate(gate.head.name)
    rng = np.random.default_rng(4)
    last = t.neutral_tick.copy()
    kinds = set()
    for k in range(120):
        if k % 3 == 2:
            req = last.copy()  # hold
        else:
            size = t.max_step_tick * (3.0 if k % 5 == 0 else 0.4)
            req = np.clip(last + rng.uniform(-1, 1, t.n) * size, t.min_tick, t.max_tick).astype(np.int64)
        goals = dict(zip(t.ids, req.tolist(), strict=True))
        prev = dict(zip(t.ids, last.tolist(), strict=True))
        v = gate.check(goals, prev)
        fresh._memo = (b"", [])  # the reference never reuses a result
        w = fresh.check(goals, prev)
        assert (v.kind, v.goals_tick, v.checks) == (w.kind, w.goals_tick, w.checks)
        kinds.add(v.kind)
        last = np.array([v.goals_tick[i] for i in t.ids])
    assert "accept" in kinds and "clip" in kinds


def test_exact_memo_answers_like_the_exact_test(gate_fm: tuple[TwinGate, Any]) -> None:
    """The last exact answer per pair is reused only for the very same transforms: repeated, partly
    repeated and new poses all answer as fcl does afresh."""
    gate, _ = gate_fm
    col = gate.collisions
    tree = col.tree
    rng = np.random.default_rng(8)
    q = rng.uniform(tree.lower_deg, tree.upper_deg, size=(80, len(tree.names)))
    edge = rng.random(q.shape) < 0.5  # half the joints at a stop, where parts meet
    q = np.where(edge, np.where(rng.random(q.shape) < 0.5, tree.lower_deg, tree.upper_deg), q)
    q[1::4] = q[0::4]  # the same pose twice in a row
    q[2::4, : len(tree.names) // 2] = q[1::4, : len(tree.names) // 2]  # some joints kept
    world = tree.world(q)
    hits = 0
    for k in range(len(q)):
        for spec in col.specs:
            ta, tb = col.part_transform(spec.a, world[k]), col.part_transform(spec.b, world[k])
            fresh = col.exact.collide(f"{spec.a}@{spec.tolerance_mm}", f"{spec.b}@{spec.tolerance_mm}", ta, tb)
            assert col._collide(spec, world[k]) == fresh
            hits += fresh
    assert hits > 0 or gate.head.name == "human"  # the human's parts never meet inside the joint stops


def test_vectorised_coupling_ok_matches_rule_by_rule() -> None:
    from servoface.sim.gate.coupling import CouplingCheck, CouplingLimit

    roles = ("a", "b", "c", "d")
    rules = (
        CouplingLimit("past", ("a", "b"), 0.5),
        CouplingLimit("neg", ("b", "c", "d"), 0.3, direction="-"),
        CouplingLimit("sum", ("a", "c"), 0.9, kind="sum_at_most", direction="any"),
        CouplingLimit("sum+", ("a", "b", "c", "d"), 1.2, kind="sum_at_most"),
    )
    check = CouplingCheck(rules, roles)
    shares = np.random.default_rng(3).uniform(-1, 1, size=(500, 4))
    expected = np.ones(500, dtype=bool)
    for score, limit in check._scores(shares):
        expected &= score <= limit
    got = check.ok(shares)
    assert np.array_equal(got, expected) and 0 < got.sum() < 500
    assert [bool(check.ok(row)) for row in shares[:50]] == expected[:50].tolist()
    assert [bool(x) for x in check.ok(shares.reshape(25, 20, 4)).ravel()] == expected.tolist()
