"""The wire property at 10^4 examples: the real pipeline (muscle model -> calibration -> twin gate -> driver ->
stock dynamixel-sdk) on the in-process emulated chain, everything on the emulator's manual clock, so an
example costs milliseconds and no wall time enters the check.

Hypothesis draws both the commands (extreme and malformed AU maps, expression apexes at any intensity, gaze
poses for targets far apart) and the call pattern (steps back to back with no time between them, short and
long gaps, a late frame followed by an on-time one, a speculative next frame, ``hold()`` in between).
Checked from the emulator's side of the wire, on every Goal Position it decoded:

- every goal inside the servo's calibrated position limits;
- speed per second: a goal moves at most ``max_step_tick * min(1, dt / T)`` from the servo's previous goal
  on the wire, ``dt`` the time between those two writes (the emulator's stamps), ``T`` the frame period;
- acceleration per second: the step rate (``step / min(1, dt / T)``, ticks per frame period) grows by at most
  ``max_speedup_tick * min(1, dt / T)`` over the previous interval of that servo in the same direction
  (from rest, or after a reversal: at most that much outright);
- a malformed command raises the package's typed error and puts nothing on the wire.

The chain, driver and pipeline are built once per module (the driver reads with Fast Sync Read, its
option of one combined reply, to keep an example cheap; the goals go out by the same Sync Write as always).
An example either starts afresh (a cheap reset: the emulated servos are sent back to neutral behind the
driver's back, 1 s on the manual clock, the pipeline is pinned there and holds it once, the gate forgets its
step, the packet log is emptied) or carries on where the one before left the head: the examples of a run add
up to one long random walk, checked throughout (the checker keeps each servo's last goal write). The run is
derandomized: CI sees the same 10^4 examples every time. The real-clock property (tests/fuzz/test_fuzz_wire.py,
25 examples, wall-time pauses) stays. Mutation checks (by hand, see the notes): with the per-time caps off
(``Pipeline.per_time_caps = False``) this fails at once on the speed cap; with the speed-up cap scaled by
``f`` instead of ``f²`` in `servoface.sim.gate.limits.per_time` it fails on the acceleration cap.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from servoface.calibration import CalibrationError
from servoface.controller.alive.gaze import gaze_config_for, solve_look_at
from servoface.controller.alive.gaze_layer import angles_to_aus
from servoface.controller.errors import ControllerError
from servoface.controller.head_servos import servo_specs, temperature_limits_c
from servoface.controller.pipeline import Pipeline
from servoface.controller.service.opening import head_calibration
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.emulator.chain import GOAL_ADDRESS
from servoface.hardware.emulator.packet_log import register_writes
from servoface.sim.errors import SimError
from servoface.sim.expressions import load_library
from servoface.sim.heads import load_head

from tests.fuzz.strategies import HUGE, fuzz_settings

EXAMPLES = int(os.environ.get("SERVOFACE_WIRE_STEP_EXAMPLES", "10000"))  # >= 10^4 in CI

HEAD = load_head("human")
LIBRARY = load_library(HEAD.expressions_path or HEAD.face_type)
APEXES = [LIBRARY[name].apex() for name in sorted(LIBRARY)]
_GAZE = gaze_config_for(HEAD.face_type, HEAD)
GAZE_POINTS_MM = [  # far apart: hard left/right/up/down, near and far
    (x, y, z)
    for x in (-2000.0, -300.0, 0.0, 300.0, 2000.0)
    for y in (-1500.0, 0.0, 1500.0)
    for z in (80.0, 600.0, 5000.0)
]


def _gaze_aus(point: tuple[float, float, float]) -> dict[str, float]:
    g = solve_look_at(point, _GAZE)
    aus = angles_to_aus(HEAD.face_type, _GAZE, g.head_yaw_deg, g.head_pitch_deg, g.eye_yaw_deg, g.eye_pitch_deg)
    return {au: v for au, v in aus.items() if abs(v) > 1e-9}


GAZES = [_gaze_aus(p) for p in GAZE_POINTS_MM]
EXTREMES: list[dict[str, float]] = [
    {},
    {"AU26": 1.0, "AU1": 1.0, "AU2": 1.0, "AU12": 1.0, "AU51": 1.0, "AU53": 1.0, "AU61": 1.0},
    {"AU27": 1.0, "AU4": 1.0, "AU15": 1.0, "AU52": 1.0, "AU54": 1.0, "AU62": 1.0, "AU43": 1.0},
    {"AU12L": 1.0, "AU15R": 1.0, "AU51": 1.0},
    {"AU12R": 1.0, "AU15L": 1.0, "AU52": 1.0},
]
AU_NAMES = sorted({au for pose in EXTREMES + APEXES + GAZES for au in pose})
MALFORMED: list[Any] = [
    {"AU12": math.nan},
    {"AU12": math.inf},
    {"AU26": -math.inf},
    {"AU12": 10**400},
    {"AU12": 1e308},
    {"AU12": "0.5"},
    {"AU12": None},
    {"AU12": [0.5]},
    {"AU99": 0.5},
    {" AU12": 0.5},
    {"AU１２": 0.5},
    {"\x1b[31mAU12": 0.5},
    {"AU12\n": 0.5},
    {"": 0.5},
]

_scaled = st.tuples(st.sampled_from(APEXES + GAZES), st.floats(0.0, 1.0)).map(
    lambda pi: {au: v * pi[1] for au, v in pi[0].items()}
)
poses = st.one_of(
    st.sampled_from(EXTREMES),
    st.sampled_from(APEXES),
    st.sampled_from(GAZES),
    _scaled,
    st.dictionaries(st.sampled_from(AU_NAMES), st.floats(-0.5, 1.5) | st.sampled_from([0.0, 1.0]), max_size=8),
    st.sampled_from(MALFORMED),
    st.dictionaries(st.sampled_from(AU_NAMES), HUGE | st.floats(allow_nan=True, allow_infinity=True), max_size=2),
)
# time before each call, s (manual clock): none at all (back to back), under a frame, a frame, a late frame,
# far longer than the Bus Watchdog (0.1 s) and than a whole motion
gaps_s = st.sampled_from([0.0, 0.0, 0.0005, 0.001, 0.004, 0.01, 0.0199, 0.02, 0.02, 0.0201, 0.035, 0.06, 0.3, 2.0])
calls = st.lists(  # (pose, gap before the call, how, repeats); a hold is one call
    st.tuples(
        poses, gaps_s, st.sampled_from(["step", "step", "step", "ahead", "hold"]), st.sampled_from([1, 1, 1, 2, 4])
    ),
    min_size=1,
    max_size=2,
)
# an example starts from neutral at rest, or (most of the time) where the one before left the head: the
# examples of a run then add up to one long random walk through poses and call patterns, checked throughout
starts = st.sampled_from(["fresh", "carry", "carry"])


@dataclass
class Rig:
    chain: Any
    driver: Driver
    pipeline: Pipeline
    neutral: dict[int, int]
    limits: dict[int, tuple[int, int]]
    step_cap: dict[int, int]  # ticks per frame period
    speedup_cap: dict[int, int]  # ticks per frame period, per frame period
    period_s: float
    wire: dict[int, tuple[float, int, float]]  # what the checker knows of each servo's last goal write


@pytest.fixture(scope="module")
def rig() -> Iterator[Rig]:
    cal = head_calibration(HEAD)
    specs = servo_specs(HEAD, cal)
    chain = ServoChain.create([(s.servo_id, s.model) for s in specs], wire_time=False, clock="manual")
    neutral = {s.servo_id: cal.by_id(s.servo_id).neutral_tick for s in specs}
    for sid, tick in neutral.items():
        chain.servo(sid).move_by_hand(tick)
    bus = open_bus("dynamixel", port=chain, baud=1_000_000)
    driver = Driver(bus, specs, clock=chain.clock, fast_sync_read=True)
    driver.configure()
    pipeline = Pipeline(HEAD, cal, driver=driver, temperature_limits_c=temperature_limits_c(specs), clock=chain.clock)
    driver.torque_on()
    pipeline.pin_to(neutral)
    pipeline.last_snapshot = driver.read_state()
    pipeline.last_write_s = pipeline.clock()
    table = pipeline.gate.table
    try:
        yield Rig(
            chain,
            driver,
            pipeline,
            neutral,
            cal.position_limits_tick(),
            {sid: int(table.max_step_tick[i]) for i, sid in enumerate(table.ids)},
            {sid: int(table.max_speedup_tick[i]) for i, sid in enumerate(table.ids)},
            pipeline.gate.frame_period_s,
            {},
        )
    finally:
        driver.close(torque_off=True)
        chain.close()


def _reset(rig: Rig) -> None:
    """Back at neutral, at rest, with an empty packet log that starts with one baseline goal write."""
    for sid, tick in rig.neutral.items():  # torque stays on: the servos travel back on their own
        rig.chain.servo(sid).write_register(GOAL_ADDRESS, tick)
    rig.chain.advance(1.0)
    rig.pipeline.pin_to(rig.neutral)
    del rig.chain.log[:]
    rig.wire.clear()
    rig.pipeline.hold()  # the baseline: neutral on the wire, the gate from rest


def wire_violations(rig: Rig, log: list[Any]) -> list[tuple[Any, ...]]:
    """Every goal write in ``log`` that breaks a limit, the speed cap or the acceleration cap per second
    (see the module docstring), carrying on from ``rig.wire`` (a servo's first write is its baseline)."""
    bad: list[tuple[Any, ...]] = []
    last = rig.wire  # sid -> (t_s, goal, step rate of the interval ending there)
    for t, sid, goal in register_writes(log, GOAL_ADDRESS, 4):
        lo, hi = rig.limits[sid]
        if not lo <= goal <= hi:
            bad.append(("limit", round(t, 4), sid, goal, (lo, hi)))
        if sid not in last:
            last[sid] = (t, goal, 0.0)
            continue
        t0, g0, rate0 = last[sid]
        f = min(1.0, (t - t0) / rig.period_s)
        step = goal - g0
        if abs(step) > rig.step_cap[sid] * f + 1e-9:
            bad.append(("speed", round(t, 4), sid, step, round(rig.step_cap[sid] * f, 2)))
        rate = step / f if f > 0 else 0.0  # ticks per frame period over this interval
        same_way = rate * rate0 > 0
        grew = abs(rate) - abs(rate0) if same_way else abs(rate)
        if grew > rig.speedup_cap[sid] * f + 1e-6:
            bad.append(("accel", round(t, 4), sid, round(rate0, 1), round(rate, 1), round(rig.speedup_cap[sid] * f, 2)))
        last[sid] = (t, goal, rate)
    return bad


def run_pattern(rig: Rig, pattern: list[tuple[Any, float, str, int]]) -> None:
    pipeline, chain = rig.pipeline, rig.chain
    for k, (aus, gap_s, how, repeats) in enumerate(pattern):
        for r in range(repeats):
            chain.advance(gap_s)
            before = len(chain.log)
            if how == "hold":
                pipeline.hold()
                break
            nxt = aus if r < repeats - 1 else (pattern[k + 1][0] if k + 1 < len(pattern) else None)
            try:
                pipeline.step(aus, next_frame=nxt if how == "ahead" else None)
            except (ControllerError, SimError, CalibrationError) as err:
                assert str(err)
                assert len(chain.log) == before, "a refused frame put packets on the wire"
                break  # the caller got the error: on to the next command


@fuzz_settings(EXAMPLES)
@given(starts, calls)
def test_no_command_or_call_pattern_breaks_limits_or_per_second_caps(rig: Rig, start: str, pattern: Any) -> None:
    if start == "fresh" or not rig.wire:
        _reset(rig)
    run_pattern(rig, pattern)
    log = list(rig.chain.log)
    del rig.chain.log[:]  # decoded once: the log stays short however long the run
    bad = wire_violations(rig, log)
    assert bad == [], bad[:5]


def test_the_checker_sees_a_cap_broken_on_the_wire(rig: Rig) -> None:
    """The mutation check kept as a test: with the per-time caps off, back-to-back steps break the speed cap
    per second on the wire, and the checker says so."""
    _reset(rig)
    rig.pipeline.per_time_caps = False
    try:
        run_pattern(rig, [({"AU26": 1.0, "AU1": 1.0, "AU51": 1.0}, 0.0, "step", 6)])
    finally:
        rig.pipeline.per_time_caps = True
    kinds = {v[0] for v in wire_violations(rig, list(rig.chain.log))}
    _reset(rig)
    assert "speed" in kinds
