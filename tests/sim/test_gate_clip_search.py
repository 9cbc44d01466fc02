"""The clip search's reuse of known answers (`TwinGate._scale_back` passes the answers of the commands it has
checked to `_last_ok`, so a round's top candidate, which is always one already checked, and truncation repeats
are not checked again) gives the same verdicts, goals, fractions and findings as the plain search (a copy of
the search before the reuse, kept here) on random walks of both built-in heads, small steps and oversized
ones that get clipped."""

from __future__ import annotations

import types
from typing import Any

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate
from servoface.sim.gate import limits as lim


def _plain_last_ok(self: TwinGate, goals: Any, suspects: tuple[int, ...] = (), known: Any = None) -> int | None:
    """`TwinGate._last_ok` before the reuse: every candidate fully checked from the end."""
    targets, angles, world, pulls = self._pose_arrays(goals)
    coupling_ok = np.flatnonzero(self.coupling.ok(self._shares(targets)))
    s = self.config.strain
    col = self.collisions
    for k in (int(i) for i in coupling_ok[::-1]):
        if any(col._collide(col.specs[p], world[k]) for p in suspects):
            continue
        flags = col.broad.flag(world[k], angles[k])
        if any(col._collide(col.specs[p], world[k]) for p in np.flatnonzero(flags) if p not in suspects):
            continue
        offsets = self.skin_source.offsets_rows(pulls[k], self.skin.fast_vertices)
        stretch, comp, flips = self.skin.measure_one(world[k], offsets, self._static(goals[k]))
        if stretch <= s.max_stretch and comp >= s.min_compression and flips <= s.max_flipped:
            self._memo = (goals[k].tobytes(), [])
            return k
    return None


def _plain_scale_back(
    self: TwinGate,
    req: Any,
    last: Any,
    last_step: Any,
    table: lim.ServoTable,
    skip_full: bool = False,
    suspects: tuple[int, ...] = (),
    rate_last: Any = None,
) -> tuple[Any, float]:
    """`TwinGate._scale_back` before the reuse."""
    step = req - last
    base = last if rate_last is None else rate_last
    lo, hi = 0.0, 1.0
    best = None
    best_frac = 0.0
    cand_1 = lim.clamp(req, base, last_step, table)
    if not (skip_full and np.array_equal(cand_1, req)) and _plain_last_ok(self, cand_1[None, :], suspects) == 0:
        return cand_1, 1.0
    for _ in range(max(1, self.config.bisection_rounds)):
        fracs = lo + (hi - lo) * np.arange(1, 9) / 8.0
        raw = last + np.trunc(fracs[:, None] * step[None, :]).astype(np.int64)
        cands = lim.clamp(raw, base, last_step, table)
        found = _plain_last_ok(self, cands, suspects)
        if found is None:
            hi = fracs[0]
            continue
        g = found
        best, best_frac = cands[g], float(fracs[g])
        lo = float(fracs[g])
        hi = float(fracs[g + 1]) if g + 1 < len(fracs) else hi
        if g + 1 >= len(fracs):
            break
    return best, best_frac


@pytest.fixture(scope="module", params=["human", "dog"])
def gate(request: pytest.FixtureRequest) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(request.param)
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig())


def _verdict_tuple(v: Any) -> tuple[Any, ...]:
    return (v.kind, v.goals_tick, v.step_fraction, tuple((f.check, f.message, f.parts) for f in v.findings))


@pytest.mark.parametrize("scale", [0.25, 3.0])
def test_clip_search_reuse_matches_the_plain_search(gate: TwinGate, scale: float) -> None:
    rng = np.random.default_rng(11)
    t = gate.table
    last = t.neutral_tick.copy()
    gate.reset()
    plain = types.MethodType(_plain_scale_back, gate)
    kinds: dict[str, int] = {}
    for _ in range(120 if scale < 1 else 60):
        req = np.clip(last + rng.uniform(-1, 1, t.n) * t.max_step_tick * scale, t.min_tick, t.max_tick)
        goals = dict(zip(t.ids, req.astype(np.int64).tolist(), strict=True))
        prev = dict(zip(t.ids, last.tolist(), strict=True))
        memory, memo = gate.step_state(), gate._memo
        gate._scale_back = plain  # type: ignore[method-assign]
        try:
            want = gate.check(goals, prev)
        finally:
            del gate._scale_back
        want_memory, want_memo = gate.step_state(), gate._memo
        gate.restore_step_state(memory)
        gate._memo = memo
        got = gate.check(goals, prev)
        assert _verdict_tuple(got) == _verdict_tuple(want)
        assert gate.step_state().same(want_memory)
        assert gate._memo[0] == want_memo[0]
        kinds[got.kind] = kinds.get(got.kind, 0) + 1
        last = np.array([got.goals_tick[i] for i in t.ids], dtype=np.int64)
    assert kinds.get("clip", 0) >= 3  # the walks exercise the search
