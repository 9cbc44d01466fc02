"""A paced frame is held to its slot (`Pipeline._slot_deficit`, `_slot`, `_hold_to_slot`): a frame a little
less than its slot after the last write (a period less that write's own time) is checked with the caps of
that elapsed time and sent no earlier than that after the last write, so held writes begin a period apart
and do not drift. The safety invariant: the per-time caps are never computed for more time than really
passes before the write. Shown from what was recorded: the clock when each `Driver.cycle_start` began and
ended, against the elapsed time each check (or used speculation) of the next frame was made for, over frames
that come early within the hold share, early beyond it, late and back to back."""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping

import numpy as np
import pytest
from servoface.controller.face import Face
from servoface.controller.pipeline import PACE_MAX_SHARE
from servoface.hardware.snapshot import ChainSnapshot
from servoface.sim.gate import ServoHealth, Verdict
from servoface.sim.gate import limits as lim

from tests.controller.pipeline_pairs import au_names, random_frames


@pytest.fixture
def face() -> Iterator[Face]:
    f = Face.open("human", emulate=True, wire_time=False)
    try:
        f.pipeline.temperature_limits_c = {}
        yield f
    finally:
        f.close(ease_s=0.0)


class _Recorder:
    """Notes the elapsed time of every gate check / used speculation and the clock around each write (the
    speculative checks of the next frame, made while the replies are on the wire, are not noted)."""

    def __init__(self, face: Face) -> None:
        p = face.pipeline
        driver = p.driver
        assert driver is not None
        self.elapsed: list[float | None] = []
        self.writes: list[tuple[float, float]] = []
        gate, check, remember, cycle_start = p.gate, p.gate.check, p.gate.remember_check, driver.cycle_start
        cycle_finish = driver.cycle_finish
        on_wire = [False]

        def checking(
            goals: Mapping[int, int],
            last: Mapping[int, int],
            health: Mapping[int, ServoHealth] | None = None,
            elapsed_s: float | None = None,
        ) -> Verdict:
            if not on_wire[0]:
                self.elapsed.append(elapsed_s)
            return check(goals, last, health, elapsed_s=elapsed_s)

        def remembering(
            verdict: Verdict,
            last: Mapping[int, int],
            health: Mapping[int, ServoHealth] | None = None,
            elapsed_s: float | None = None,
        ) -> None:
            self.elapsed.append(elapsed_s)
            remember(verdict, last, health, elapsed_s)

        def starting(goals: Mapping[int, int]) -> None:
            t0 = p.clock()
            cycle_start(goals)
            self.writes.append((t0, p.clock()))
            on_wire[0] = True

        def finishing() -> ChainSnapshot:
            on_wire[0] = False
            return cycle_finish()

        gate.check = checking  # type: ignore[method-assign]
        gate.remember_check = remembering  # type: ignore[method-assign]
        driver.cycle_start = starting  # type: ignore[method-assign]
        driver.cycle_finish = finishing  # type: ignore[method-assign]


@pytest.mark.parametrize("speculate", [False, True])
def test_caps_are_never_for_more_time_than_passes_before_the_write(face: Face, speculate: bool) -> None:
    p = face.pipeline
    p.per_time_caps = True
    p.speculate_gate = speculate
    period_s = p.gate.frame_period_s
    rec = _Recorder(face)
    frames = random_frames(au_names(p), 90, seed=17, jump=0.1, move=0.6, sigma=0.1)
    # when each frame comes, as a share of a period after the last write: a paced loop a little early (held),
    # early beyond the hold share (not held: shrunk caps), late, and back to back (a caller faster than the
    # rate: not held once it has come short twice in a row)
    arrive = [0.97, 0.9, 0.8, 0.95, 0.5, 0.92, 1.1, 0.9, 0.0, 0.0, 0.0, 0.0, 0.9, 0.85, 0.6, 0.99]
    short_runs: list[int] = []
    checks: list[list[float | None]] = []
    used: list[float | None] = []
    slots: list[float] = []
    bounds: list[tuple[float | None, float | None, float | None]] = []
    for k, aus in enumerate(frames):
        last_write_s = p.last_write_s
        assert last_write_s is not None
        wait_s = last_write_s + arrive[k % len(arrive)] * period_s - time.monotonic()
        if wait_s > 0:
            time.sleep(wait_s)
        short_runs.append(p._short_run)
        slots.append(p._slot())
        n = len(rec.elapsed)
        p.step(aus, next_frame=frames[k + 1] if k + 1 < len(frames) else None)
        checks.append(rec.elapsed[n:])  # one check or used speculation, and one more if `_pay_back` tried
        assert checks[-1] and len(checks[-1]) <= 2
        bounds.append((p.last_slot_start_s, p.last_write_began_s, p.last_write_s))
        used.append(p._checked_s)  # the elapsed time of the verdict sent (`_pay_back` may discard its check)
        assert used[-1] in checks[-1]
        assert p.gate.step_state().last_fraction == lim.time_fraction(used[-1], period_s)  # (its memory)
    assert len(rec.writes) == len(frames)
    held = paid = 0
    for k in range(1, len(frames)):
        elapsed_s = used[k]
        assert elapsed_s is not None
        passed_s = rec.writes[k][0] - rec.writes[k - 1][1]  # from the end of one write to the start of the next
        assert passed_s >= elapsed_s, (k, passed_s, checks[k])  # the invariant
        slot_start_s, began_s, ended_s = bounds[k - 1]  # the last write as the pipeline timed it (around ours)
        assert slot_start_s is not None and began_s is not None and ended_s is not None
        assert slot_start_s <= began_s <= rec.writes[k - 1][0] and rec.writes[k - 1][1] <= ended_s
        # the slot: a period from where the last slot began (at most PACE_MAX_SHARE of a period less)
        assert slots[k] == period_s - min(ended_s - slot_start_s, PACE_MAX_SHARE * period_s)
        if slots[k] in checks[k]:  # held (checked for exactly its slot: sent no earlier), or paid back
            held += elapsed_s == slots[k]
            paid += elapsed_s < slots[k]
            assert short_runs[k] < 2  # a caller faster than the rate is never held
            if elapsed_s == slots[k]:  # held: its slot began where it was held to, a period after the last one's
                assert bounds[k][0] == ended_s + slots[k]
                if ended_s - slot_start_s < PACE_MAX_SHARE * period_s:  # on the grid (1 ns: float rounding)
                    assert abs(bounds[k][0] - (slot_start_s + period_s)) < 1e-9, (k, bounds[k], slot_start_s)
    assert held >= 5 and paid >= 1, (held, paid)  # (a loaded machine may make some frames late)
    assert any(e is not None and e < (1.0 - PACE_MAX_SHARE) * period_s for e in rec.elapsed)  # not held


def test_a_manual_clock_is_never_held(face: Face) -> None:
    """A test's clock (not `time.monotonic`) owns time: a frame a little short of a period is checked with
    the caps of the time the clock says, as before the hold existed."""
    p = face.pipeline
    p.per_time_caps = True
    period_s = p.gate.frame_period_s
    now = [100.0]
    p.clock = lambda: now[0]
    p.last_write_s = now[0]
    rec = _Recorder(face)
    frames = random_frames(au_names(p), 12, seed=3, jump=0.2, move=0.8, sigma=0.2)
    for aus in frames:
        now[0] += 0.9 * period_s  # within the hold share on the real clock
        p.step(aus)
    assert np.allclose([e for e in rec.elapsed if e is not None], 0.9 * period_s)
    assert len(rec.elapsed) == len(frames)
