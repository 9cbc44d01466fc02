"""A rate clip checks the clamped command's state first (`TwinGate.check`): the request, which the limits
and rate caps clamp, is not what will be sent, so its own state checks (skin strain, flips, contacts) run
only when the clamped command fails them (for the search's hints). The verdicts are those of the old
order (the request's state checked first, then the clamped command): the same kind, goals and step
fraction; the findings the same but for the request's own state findings when the clamped command passed
(the reasons name what stopped the request being sent: its speed). Where the clamped command fails too,
the request's state is measured and the search runs as before."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate

STATE_CHECKS = frozenset({"coupling", "strain", "flip", "collision"})


@pytest.fixture(scope="module", params=["human", "dog"])
def gate(request: pytest.FixtureRequest) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(request.param)
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig())


def _old_order(gate: TwinGate, goals: dict[int, int], prev: dict[int, int]) -> Any:
    """`check` as it was: the clamped command is never tried first."""
    gate._clamped_passes = lambda clamped, known: False  # type: ignore[method-assign]
    try:
        return gate.check(goals, prev)
    finally:
        del gate._clamped_passes


@pytest.mark.parametrize(("scale", "seed", "frames"), [(0.6, 5, 150), (3.0, 7, 80)])
def test_rate_clips_give_the_old_orders_verdicts(gate: TwinGate, scale: float, seed: int, frames: int) -> None:
    rng = np.random.default_rng(seed)
    t = gate.table
    last = t.neutral_tick.copy()
    gate.reset()
    early = searched = 0
    for _ in range(frames):
        req = np.clip(last + rng.uniform(-1, 1, t.n) * t.max_step_tick * scale, t.min_tick, t.max_tick)
        goals = dict(zip(t.ids, req.astype(np.int64).tolist(), strict=True))
        prev = dict(zip(t.ids, last.tolist(), strict=True))
        memory, memo = gate.step_state(), gate._memo
        want = _old_order(gate, goals, prev)
        want_memory = gate.step_state()
        gate.restore_step_state(memory)
        gate._memo = memo
        calls: list[bytes] = []
        real = gate._hard_findings

        def counted(goal: Any, stop_early: bool = False, real: Any = real, calls: list[bytes] = calls) -> Any:
            calls.append(goal.tobytes())
            return real(goal, stop_early)

        gate._hard_findings = counted  # type: ignore[method-assign]
        try:
            got = gate.check(goals, prev)
        finally:
            del gate._hard_findings
        assert (got.kind, got.goals_tick, got.step_fraction) == (want.kind, want.goals_tick, want.step_fraction)
        assert gate.step_state().same(want_memory)
        got_f = [(f.check, f.message) for f in got.findings]
        want_f = [(f.check, f.message) for f in want.findings]
        missing = [f for f in want_f if f not in got_f]
        assert all(f in want_f for f in got_f)
        assert all(check in STATE_CHECKS for check, _ in missing), missing
        request = np.array([goals[i] for i in t.ids], dtype=np.int64).tobytes()
        if got.kind == "clip" and got.step_fraction == 1.0 and {f.check for f in got.findings} & {"speed", "accel"}:
            early += 1
            assert request not in calls  # the request's own state was never measured
        if got.step_fraction < 1.0 and {f.check for f in got.findings} & {"speed", "accel"}:
            searched += 1  # the clamped command failed too: the request's state was measured for the hints
            assert request in calls
        last = np.array([got.goals_tick[i] for i in t.ids], dtype=np.int64)
    assert early >= 5  # the walks exercise the shortcut
    if scale > 1.0:
        assert searched >= 3, searched  # and rate clips whose clamped command fails (the search as before)
