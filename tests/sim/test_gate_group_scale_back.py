"""The scale-back slows only the servos that move what the request failed on (`TwinGate._uninvolved`): on a
collision, the servos driving either part's chain; on strain or flips, the servos moving the skin. The others
keep their whole clamped step (the dog's ears and eyes while its jaw is held off the teeth; the human's eyes and
lids while its skin is over-stretched), and every verdict is still a command that passes every check. Random
walks of both built-in heads, small steps (as the gate bench) and oversized ones."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate
from servoface.sim.gate import limits as lim


@pytest.fixture(scope="module", params=["human", "dog"])
def gate(request: pytest.FixtureRequest) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(request.param)
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig())


def _walk(gate: TwinGate, scale: float, frames: int, seed: int, on_clip: Any) -> None:
    """A random walk from neutral; ``on_clip(verdict, requested, last, memory)`` for every clip."""
    rng = np.random.default_rng(seed)
    t = gate.table
    last = t.neutral_tick.copy()
    gate.reset()
    for _ in range(frames):
        req = np.clip(last + rng.uniform(-1, 1, t.n) * t.max_step_tick * scale, t.min_tick, t.max_tick)
        goals = dict(zip(t.ids, req.astype(np.int64).tolist(), strict=True))
        prev = dict(zip(t.ids, last.tolist(), strict=True))
        memory = gate.step_state()
        verdict = gate.check(goals, prev)
        if verdict.kind == "clip":
            on_clip(verdict, goals, prev, memory)
        last = np.array([verdict.goals_tick[i] for i in t.ids], dtype=np.int64)


@pytest.mark.parametrize(("scale", "frames"), [(0.25, 1500), (3.0, 300)])
def test_uninvolved_servos_keep_their_whole_clamped_step(gate: TwinGate, scale: float, frames: int) -> None:
    """Wherever the search scaled only the servos involved, the free ones sit at the clamped request and have
    moved at least as far as the all-servo search (the old one, run on the same frame and memory) moves them,
    and further in some frames."""
    real = gate._scale_back
    seen = {"free": 0, "further": 0, "fallback": 0}

    def watched(req: Any, last: Any, last_step: Any, table: lim.ServoTable, **kw: Any) -> Any:
        best, frac = real(req, last, last_step, table, **kw)
        free = kw.get("free")
        if free is None or best is None:
            return best, frac
        base = kw.get("rate_last")
        cand_1 = lim.clamp(req, last if base is None else base, last_step, table)
        if not np.array_equal(best[free], cand_1[free]):  # no free candidate passed: every servo scaled
            seen["fallback"] += 1
            return best, frac
        memo = gate._memo
        plain, _ = real(req, last, last_step, table, **{**kw, "free": None})
        gate._memo = memo
        if plain is not None:
            moved, moved_plain = np.abs(best - last)[free], np.abs(plain - last)[free]
            assert np.all(moved >= moved_plain), (moved, moved_plain)
            seen["further"] += int(np.any(moved > moved_plain))
        seen["free"] += 1
        return best, frac

    gate._scale_back = watched  # type: ignore[method-assign]
    try:
        _walk(gate, scale, frames, seed=0, on_clip=lambda *a: None)
    finally:
        del gate._scale_back
    assert seen["free"] >= 5 and seen["further"] >= 5, seen


@pytest.mark.parametrize(("scale", "frames"), [(0.25, 500), (3.0, 100)])
def test_every_clip_passes_when_checked_again(gate: TwinGate, scale: float, frames: int) -> None:
    """A clip's goals, checked from the same last command and memory, are accepted: inside the limits and rate
    caps, no contact, strain, flip or coupling finding. (Found by a search that scales only some servos or by
    the fallback that scales them all.)"""
    clips: list[tuple[Any, ...]] = []

    def note(verdict: Any, goals: Any, prev: Any, memory: Any) -> None:
        clips.append((dict(verdict.goals_tick), prev, memory))

    _walk(gate, scale, frames, seed=9, on_clip=note)
    assert len(clips) >= 10
    for goals, prev, memory in clips:
        gate.restore_step_state(memory)
        again = gate.check(goals, prev)
        assert again.kind == "accept", again


def test_the_masks_name_the_servos_that_move_the_parts() -> None:
    """The dog's jaw does not move its ears or eyes: a jaw / teeth contact frees them, and the jaw stays
    involved; skin findings free the human's eyes and lids and nothing that pulls the skin; a coupling rule
    or any other finding beside them frees none."""
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.gate.verdict import Finding
    from servoface.sim.heads import load_head

    for name, finding, free_roles, involved_roles in (
        ("dog", Finding("collision", "contact", parts=("jaw", "teeth_upper")), ("ear_pan_l", "eye_pan"), ("jaw",)),
        ("human", Finding("strain", "skin edge stretched"), ("eye_pan_l", "upper_lid_l"), ("jaw",)),
    ):
        head = load_head(name)
        g = TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig())
        free = g._uninvolved([finding])
        assert free is not None
        roles = dict(zip(g.poser.roles, free.tolist(), strict=True))
        assert all(roles[r] for r in free_roles), roles
        assert not any(roles[r] for r in involved_roles), roles
        for other in (Finding("coupling", "rule"), Finding("input", "bad value")):
            assert g._uninvolved([finding, other]) is None  # a coupling rule or anything else: none freed


def test_it_never_holds_where_scaling_every_servo_would_not(gate: TwinGate) -> None:
    """Each frame of a small-step walk checked both ways from the same memory: a hold (reject) of the search
    that frees servos is always a hold of the all-servo search too (its fallback is that search), and it holds
    less often on these walks (2000 frames: 18 -> 9 human, 15 -> 7 dog)."""
    real = gate._uninvolved
    rng = np.random.default_rng(0)
    t = gate.table
    last = t.neutral_tick.copy()
    gate.reset()
    holds = {"free": set(), "all": set()}
    try:
        for i in range(2000):
            req = np.clip(last + rng.uniform(-1, 1, t.n) * t.max_step_tick * 0.25, t.min_tick, t.max_tick)
            goals = dict(zip(t.ids, req.astype(np.int64).tolist(), strict=True))
            prev = dict(zip(t.ids, last.tolist(), strict=True))
            memory, memo = gate.step_state(), gate._memo
            for way in ("free", "all"):
                gate.restore_step_state(memory)
                gate._memo = memo
                gate._uninvolved = real if way == "free" else (lambda hard: None)  # type: ignore[method-assign]
                if gate.check(goals, prev).kind == "reject":
                    holds[way].add(i)
            gate.restore_step_state(memory)
            gate._memo = memo
            verdict = gate.check(goals, prev)  # the walk goes on as the all-servo search leads it
            last = np.array([verdict.goals_tick[s] for s in t.ids], dtype=np.int64)
    finally:
        del gate._uninvolved
    assert holds["free"] <= holds["all"], holds
    assert len(holds["free"]) < len(holds["all"]), holds
