"""The gate on the built-in human head: TSS over its real part pairs, the face model's skin, AU frames."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from servoface.sim.gate import GateConfig, TwinGate
from servoface.sim.gate.box_lsq import BoxLsq
from servoface.sim.gate.limits import clamp, step_bounds
from servoface.sim.gate.tss_build import summed_reduction


@pytest.fixture(scope="module")
def head():  # type: ignore[no-untyped-def]
    from servoface.sim.heads import load_head

    return load_head("human")


@pytest.fixture(scope="module")
def face_model(head):  # type: ignore[no-untyped-def]
    from servoface.sim.face_model import FaceModel

    return FaceModel(head)


@pytest.fixture(scope="module")
def gate(head, face_model) -> TwinGate:  # type: ignore[no-untyped-def]
    """Tables from the user cache (keyed by geometry, so never stale; the first run builds them)."""
    from servoface.calibration.fileformat import load_calibration

    cal = load_calibration(head.calibration_path)
    return TwinGate(head, cal, 1 / 60, GateConfig(), face_model=face_model)


def test_lids_and_eyeballs_are_proven_apart_and_lid_pairs_tabulated(gate: TwinGate) -> None:
    skipped = {(s.a, s.b): why for s, why in gate.collisions.skipped}
    assert "common centre" in skipped[("eyeball_l", "upper_lid_l")]
    assert "common centre" in skipped[("eyeball_r", "lower_lid_r")]
    names = {(s.a, s.b) for s in gate.collisions.specs}
    assert ("upper_lid_l", "lower_lid_l") in names and ("jaw", "teeth_upper") in names


def test_human_tss_misses_nothing_over_a_dense_sweep_and_saves_95_percent(gate: TwinGate) -> None:
    col = gate.collisions
    tree = col.tree
    rng = np.random.default_rng(11)
    flagged = 0
    for p, (spec, built) in enumerate(zip(col.specs, col.built, strict=True)):
        idx = [tree.index[j] for j in built.table.joints]
        lo, hi = tree.lower_deg[idx], tree.upper_deg[idx]
        n = 400 if built.table.n_tests or built.table.exact_only else 40
        grid = rng.uniform(lo, hi, size=(n, len(idx)))
        grid[: 2 ** len(idx)] = np.array(np.meshgrid(*zip(lo, hi, strict=True))).reshape(len(idx), -1).T[:n]
        q = np.tile(tree.neutral_deg, (len(grid), 1))
        q[:, idx] = grid
        world = tree.world(q)
        flags = col.broad.flag(world, q)[:, p]
        exact = np.array([col._collide(spec, w) for w in world])
        assert not np.any(exact & ~flags), f"TSS missed a collision of {spec.a}/{spec.b}"
        flagged += int(flags.sum())
    # the built-in human is collision-free inside its joint ranges by design (the demo head's test has
    # collisions); here the point is that the sphere tests run and flag near contacts, and save work
    assert flagged > 100
    tables = [b.table for b in col.built]
    assert summed_reduction(tables) >= 0.95
    assert all(t.reduction >= 0.95 for t in tables if t.n_tests and not t.exact_only)


def test_face_model_skin_is_exactly_pose_from_targets(gate: TwinGate, face_model, head) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(5)
    anchors = [a for a in head.actuators if a.kind == "anchor"]
    neutral = {a.role: (a.neutral_deg if a.kind == "joint" else a.neutral_mm) for a in head.actuators}
    for _ in range(25):
        p = rng.uniform([a.lower_mm - 1 for a in anchors], [a.upper_mm + 1 for a in anchors])
        ref = face_model.pose_from_targets({**neutral, **{a.role: float(v) for a, v in zip(anchors, p, strict=True)}})
        full = gate.skin_source.offsets(p)
        assert np.allclose(full, ref.skin_offset_mm, atol=1e-7)  # 30 servos: BVLS vs BoxLsq differ by ~1e-8 mm
        rows = gate.skin.active_vertices
        part = gate.skin_source.offsets_rows(p, rows)
        assert np.allclose(part, full[rows], atol=1e-12)
        world = gate.tree.world(gate.tree.neutral_deg[None, :])[0]
        assert [float(x) for x in gate.skin.measure(world, part)] == [float(x) for x in gate.skin.measure(world, full)]


def test_box_lsq_matches_the_face_models_fit(face_model) -> None:  # type: ignore[no-untyped-def]
    fit = face_model.fit
    a = np.vstack([fit.unit_pull, fit.mu * np.eye(fit.unit_pull.shape[1])])
    solver = BoxLsq(a, fit.low, fit.high)
    rng = np.random.default_rng(2)
    p = np.zeros(fit.unit_pull.shape[0])
    for k in range(60):
        p = rng.uniform(-6, 10, size=p.shape) if k % 10 == 0 else p + rng.normal(0, 0.5, size=p.shape)
        c = solver.solve(np.concatenate([p, np.zeros(a.shape[1])]))
        assert c is not None and np.allclose(c, fit.contractions(p), atol=1e-8)


def _safe(gate: TwinGate, v, last: np.ndarray, last_step: np.ndarray, req: np.ndarray) -> None:  # type: ignore[no-untyped-def]
    t = gate.table
    sent = np.array([v.goals_tick[i] for i in t.ids])
    assert np.all((sent >= t.min_tick) & (sent <= t.max_tick))
    lo, hi = step_bounds(last_step, t)
    assert np.all((sent - last >= lo) & (sent - last <= hi)) and np.all(np.abs(sent - last) <= t.max_step_tick)
    assert gate.audit(v.goals_tick) == [], v
    if v.kind == "reject":
        assert np.array_equal(sent, last)
    elif v.kind == "clip" and np.array_equal(sent, last):  # only when the clamp itself is the last command
        assert np.array_equal(clamp(req, last, last_step, t), last), v
    elif v.kind == "clip":
        assert np.abs(sent - req).sum() < np.abs(last - req).sum()
    else:
        assert np.array_equal(sent, req)


AU_NAMES = [
    "AU1",
    "AU2",
    "AU4",
    "AU5",
    "AU6",
    "AU7",
    "AU9",
    "AU10",
    "AU12L",
    "AU12R",
    "AU15",
    "AU17",
    "AU20",
    "AU23",
    "AU25",
    "AU26",
    "AU27",
    "AU43",
    "AU45",
    "AU51",
    "AU53",
    "AU61",
]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.dictionaries(st.sampled_from(AU_NAMES), st.floats(0.0, 1.0), max_size=6), min_size=1, max_size=5))
def test_au_frames_through_the_face_model_only_pass_safe_commands(gate: TwinGate, face_model, frames) -> None:  # type: ignore[no-untyped-def]
    cal = gate.poser.calibration
    t = gate.table
    known = face_model.au_names
    gate.reset()
    last = t.neutral_tick.copy()
    last_step = np.zeros(t.n, dtype=np.int64)
    for aus in frames:
        aus = {
            k: min(max(v, face_model.au_range(k)[0]), face_model.au_range(k)[1]) for k, v in aus.items() if k in known
        }
        goals = cal.targets_to_goals(face_model.solve(aus).actuator_targets)
        req = np.array([goals[i] for i in t.ids])
        v = gate.check(goals, dict(zip(t.ids, last.tolist(), strict=True)))
        _safe(gate, v, last, last_step, req)
        sent = np.array([v.goals_tick[i] for i in t.ids])
        last_step, last = sent - last, sent


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.lists(st.integers(-300, 300), min_size=30, max_size=30), min_size=1, max_size=5))
def test_random_goal_vectors_on_the_human_head(gate: TwinGate, steps: list[list[int]]) -> None:
    t = gate.table
    gate.reset()
    last = t.neutral_tick.copy()
    last_step = np.zeros(t.n, dtype=np.int64)
    for step in steps:
        req = last + np.array(step)
        v = gate.check(dict(zip(t.ids, req.tolist(), strict=True)), dict(zip(t.ids, last.tolist(), strict=True)))
        _safe(gate, v, last, last_step, req)
        sent = np.array([v.goals_tick[i] for i in t.ids])
        last_step, last = sent - last, sent
