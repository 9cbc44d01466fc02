"""Safety properties of the gate (hypothesis): whatever is requested, what passes is within limits and
rate caps, collision-free by the exact test on every pair, inside coupling and strain limits; a clip is
closer to the request than holding; a reject holds the last safe command."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from servoface.sim.gate import TwinGate, Verdict
from servoface.sim.gate.demo_rig import demo_calibration, demo_head
from servoface.sim.gate.gate import GateConfig
from servoface.sim.gate.limits import clamp, step_bounds


@pytest.fixture(scope="module")
def gate(tmp_path_factory: pytest.TempPathFactory) -> TwinGate:
    head = demo_head()
    # faster rates than the default so a few frames reach collisions, strain and coupling
    roles = [a.role for a in head.actuators]
    cfg = GateConfig(
        cache_dir=tmp_path_factory.getbasetemp() / "tss-demo",
        max_step_tick={r: 400 for r in roles},
        max_speedup_tick={r: 150 for r in roles},
    )
    return TwinGate(head, demo_calibration(head), 1 / 60, cfg)


def assert_safe(gate: TwinGate, v: Verdict, last: np.ndarray, last_step: np.ndarray, req: np.ndarray) -> None:
    t = gate.table
    sent = np.array([v.goals_tick[i] for i in t.ids])
    step = sent - last
    assert np.all(sent >= t.min_tick) and np.all(sent <= t.max_tick), v
    assert np.all(np.abs(step) <= t.max_step_tick), v
    lo, hi = step_bounds(last_step, t)
    assert np.all(step >= lo) and np.all(step <= hi), v
    assert gate.audit(v.goals_tick) == [], v
    if v.kind == "accept":
        assert np.array_equal(sent, req)
    elif v.kind == "reject":
        assert np.array_equal(sent, last)
    elif np.array_equal(sent, last):  # a clip that moves nothing: only when the clamp itself is the last
        assert np.array_equal(clamp(req, last, last_step, t), last), v
    else:
        assert np.all(np.abs(sent - req) <= np.abs(last - req))
        assert np.abs(sent - req).sum() < np.abs(last - req).sum()


ticks = st.integers(min_value=-200, max_value=4300)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.lists(ticks, min_size=7, max_size=7), min_size=1, max_size=6), st.floats(0.0, 1.0))
def test_random_goal_vectors_only_safe_commands_pass(gate: TwinGate, requests: list[list[int]], near: float) -> None:
    t = gate.table
    gate.reset()
    last = t.neutral_tick.copy()
    last_step = np.zeros(t.n, dtype=np.int64)
    for raw in requests:
        # mix wild vectors with ones near the last command (where accept/clip boundaries live)
        req = np.array(raw, dtype=np.int64)
        req = np.where(np.abs(req - last) > 600 * near + 40, last + np.sign(req - last) * (600 * near + 40), req)
        req = req.astype(np.int64)
        v = gate.check(dict(zip(t.ids, req.tolist(), strict=True)), dict(zip(t.ids, last.tolist(), strict=True)))
        assert_safe(gate, v, last, last_step, req)
        sent = np.array([v.goals_tick[i] for i in t.ids])
        last_step, last = sent - last, sent
