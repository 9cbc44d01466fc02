"""The clip search's shortcuts give the same verdicts, goals, fractions, findings and memory as the plain
search (a copy of the search before them, kept here) on random walks of both built-in heads, small steps and
oversized ones that get clipped: the reuse of known answers (`TwinGate._scale_back` passes the answers of the
commands it has checked to `_last_ok`, so a round's top candidate, which is always one already checked, and
truncation repeats are not checked again), and the skin measured first where the request failed on the skin
and not by contact (``skin_first``)."""

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
    skin_first: bool = False,
    free: Any = None,
    known: Any = None,
) -> tuple[Any, float]:
    """`TwinGate._scale_back` before the reuse and the skin-first order (``skin_first`` and ``known`` are
    ignored): the ``free`` servos at the clamped request first, then every servo scaled."""
    step = req - last
    base = last if rate_last is None else rate_last
    cand_1 = lim.clamp(req, base, last_step, table)
    if not (skip_full and np.array_equal(cand_1, req)) and _plain_last_ok(self, cand_1[None, :], suspects) == 0:
        return cand_1, 1.0
    if free is not None and not np.array_equal(cand_1[free], last[free]):
        best, frac = _plain_bisect(self, step, last, base, last_step, table, cand_1, free, suspects)
        if best is not None:
            return best, frac
    return _plain_bisect(self, step, last, base, last_step, table, cand_1, None, suspects)


def _plain_bisect(
    self: TwinGate,
    step: Any,
    last: Any,
    base: Any,
    last_step: Any,
    table: lim.ServoTable,
    cand_1: Any,
    free: Any,
    suspects: tuple[int, ...],
) -> tuple[Any, float]:
    lo, hi = 0.0, 1.0
    best = None
    best_frac = 0.0
    for _ in range(max(1, self.config.bisection_rounds)):
        fracs = lo + (hi - lo) * np.arange(1, 9) / 8.0
        raw = last + np.trunc(fracs[:, None] * step[None, :]).astype(np.int64)
        cands = lim.clamp(raw, base, last_step, table)
        if free is not None:
            cands[:, free] = cand_1[free]
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


@pytest.mark.parametrize(("scale", "seed", "frames"), [(0.25, 11, 120), (3.0, 11, 60), (0.25, 0, 400)])
def test_clip_search_reuse_matches_the_plain_search(gate: TwinGate, scale: float, seed: int, frames: int) -> None:
    rng = np.random.default_rng(seed)
    t = gate.table
    last = t.neutral_tick.copy()
    gate.reset()
    plain = types.MethodType(_plain_scale_back, gate)
    kinds: dict[str, int] = {}
    skin_first = 0
    real = gate._scale_back

    def counted(*args: Any, **kwargs: Any) -> Any:
        nonlocal skin_first
        skin_first += int(bool(kwargs.get("skin_first")))
        return real(*args, **kwargs)

    for _ in range(frames):
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
        gate._scale_back = counted  # type: ignore[method-assign]
        try:
            got = gate.check(goals, prev)
        finally:
            del gate._scale_back
        assert _verdict_tuple(got) == _verdict_tuple(want)
        assert gate.step_state().same(want_memory)
        assert gate._memo[0] == want_memo[0]
        kinds[got.kind] = kinds.get(got.kind, 0) + 1
        last = np.array([got.goals_tick[i] for i in t.ids], dtype=np.int64)
    assert kinds.get("clip", 0) >= 3  # the walks exercise the search
    if seed == 0 and gate.head.name == "human":
        assert skin_first >= 5  # the human's long small-step walk clips on skin flips: the skin-first order runs


def test_skin_first_order_matches_the_plain_candidate_check(gate: TwinGate) -> None:
    """`_last_ok` with the skin measured first gives the index the plain check gives, on the bisection
    candidates between random commands (anywhere in the limits and near neutral: candidates that fail by
    contact, on the skin, both, or pass), with and without the pairs the far end collides on as suspects."""
    t = gate.table
    rng = np.random.default_rng(23)
    wide = rng.integers(t.min_tick, t.max_tick + 1, size=(40, t.n))
    span = (t.max_tick - t.min_tick) * rng.uniform(0.05, 0.4, size=(40, 1))
    near = np.clip(t.neutral_tick + rng.uniform(-1, 1, (40, t.n)) * span, t.min_tick, t.max_tick).astype(np.int64)
    cmds = np.vstack([wide, near]).astype(np.int64)
    seen = {"contact": 0, "skin": 0, "found": 0}
    fracs = np.arange(1, 9) / 8.0
    for a, b in zip(cmds[:-1], cmds[1:], strict=True):
        cands = (a + np.trunc(fracs[:, None] * (b - a)[None, :])).astype(np.int64)
        hard = gate._hard_findings(b)
        seen["contact"] += any(f.check == "collision" for f in hard)
        seen["skin"] += any(f.check in ("strain", "flip") for f in hard)
        hit = {f.parts for f in hard if f.check == "collision"}
        suspects = tuple(p for p, s in enumerate(gate.collisions.specs) if (s.a, s.b) in hit)
        for sus in ((), suspects):
            want = _plain_last_ok(gate, cands, sus)
            assert gate._last_ok(cands, sus, None, skin_first=True) == want
            assert gate._last_ok(cands, sus, {}, skin_first=False) == want
            seen["found"] += want is not None
    # (random commands collide on the dog and strain the human's skin; both find passing candidates)
    assert seen["contact"] + seen["skin"] >= 30 and seen["found"] >= 30, seen


def test_batched_transforms_give_the_candidates_own(gate: TwinGate, monkeypatch: pytest.MonkeyPatch) -> None:
    """With three or more candidates left to check, `_last_ok` computes their joint transforms in one batch
    (`JointTree.world`) instead of one candidate at a time (`local_one`, `fill_one`): the same numbers, so the
    same index, on the bisection candidates between random commands, skin first or contact first."""
    import servoface.sim.gate.gate as gate_module

    t = gate.table
    rng = np.random.default_rng(5)
    cmds = rng.integers(t.min_tick, t.max_tick + 1, size=(30, t.n)).astype(np.int64)
    fracs = np.arange(1, 9) / 8.0
    batches = ran = 0
    real_world = gate.tree.world

    def counted(angles: Any) -> Any:
        nonlocal batches
        batches += 1
        return real_world(angles)

    monkeypatch.setattr(gate.tree, "world", counted)
    for a, b in zip(cmds[:-1], cmds[1:], strict=True):
        cands = (a + np.trunc(fracs[:, None] * (b - a)[None, :])).astype(np.int64)
        for skin_first in (False, True):
            monkeypatch.setattr(gate_module, "_BATCH_FK", 10**9)  # one candidate at a time
            one_by_one = gate._last_ok(cands, (), {}, skin_first=skin_first)
            monkeypatch.setattr(gate_module, "_BATCH_FK", 3)
            before = batches
            assert gate._last_ok(cands, (), {}, skin_first=skin_first) == one_by_one
            ran += batches > before
            assert one_by_one == _plain_last_ok(gate, cands, ())  # (its own poses are batched anyway)
    assert ran >= 20  # the batch ran (candidates that fail leave several to check)
