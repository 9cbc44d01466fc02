"""The clip search's shortcuts (answers reused for repeated candidates, `GateConfig.clip_reuse`) give the
same verdicts, clipped goals, step fractions and findings as the straightforward search, on random walks
of small and oversized steps through both built-in heads."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate


def _gate(name: str, reuse: bool) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(name)
    assert head.calibration_path is not None
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig(clip_reuse=reuse))


@pytest.fixture(scope="module", params=["human", "dog"])
def gates(request: pytest.FixtureRequest) -> tuple[TwinGate, TwinGate]:
    new = _gate(request.param, True)
    old = TwinGate.__new__(TwinGate)  # the same built twin (shared; each keeps its own step state) with
    old.__dict__.update(new.__dict__)  # the straightforward search
    old.config = dataclasses.replace(new.config, clip_reuse=False)
    return new, old


@pytest.mark.parametrize("scale", [0.25, 3.0])
def test_clip_search_gives_the_same_verdicts_with_and_without_reuse(
    gates: tuple[TwinGate, TwinGate], scale: float
) -> None:
    new, old = gates
    t = new.table
    rng = np.random.default_rng(int(scale * 100) + 7)
    clips = 0
    for _walk in range(2):
        new.reset()
        old.reset()
        last = new.neutral_goals()
        for _ in range(60):
            base = np.array([last[i] for i in t.ids])
            req = np.clip(base + rng.uniform(-1, 1, t.n) * t.max_step_tick * scale, t.min_tick, t.max_tick)
            goals = {int(i): int(v) for i, v in zip(t.ids, req.astype(np.int64), strict=True)}
            a = new.check(goals, last)
            b = old.check(goals, last)
            assert (a.kind, a.goals_tick, a.step_fraction) == (b.kind, b.goals_tick, b.step_fraction)
            assert [(f.check, f.message) for f in a.findings] == [(f.check, f.message) for f in b.findings]
            clips += a.kind == "clip" and a.step_fraction < 1.0
            last = a.goals_tick
    assert clips >= 3, clips  # the search itself ran (scaled-back clips), not only accepts
