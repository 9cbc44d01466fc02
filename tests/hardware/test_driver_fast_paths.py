"""The driver's cheap per-cycle paths give exactly what the straightforward ones give.

- `ServoRecord.freeze` (reuses the last state while only the position moved) == `freeze_lazy` (a capture of
  the values that moved, built into a state when a snapshot's servo is looked at) == `freeze_full` (built
  field by field), whatever field of the record changes;
- `check_goals`'s fast path for plain int frames accepts and refuses exactly as the full checks do;
- a `Driver` with the fast paths and one with the straightforward ones (the previous code, kept here as a
  subclass) driven by the same random commands, faults and obstacles on two identical manual-clock chains:
  the same bytes on the emulator's side of the wire, the same snapshots, the same events.
"""

from __future__ import annotations

import dataclasses
import math
import operator
import random
from collections.abc import Mapping

import numpy as np
import pytest
from servoface.hardware.bus import BusCounters, BusStats
from servoface.hardware.driver import Driver
from servoface.hardware.driver_reads import POSITION, TelemetryGroup
from servoface.hardware.errors import GoalRejectedError
from servoface.hardware.fault_policy import ThermalTrend, eased_goal
from servoface.hardware.goal_check import check_goals
from servoface.hardware.registers import HardwareErrorBits, Register, model_by_name, span
from servoface.hardware.sentinel import SENTINEL, SENTINEL_SHORT, split
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.servo_record import ServoRecord
from servoface.hardware.snapshot import ChainSnapshot, FaultKind, LazyServoStates, ServoState, build_state, peek_state

from tests.hardware.driver_helpers import DT_S, LIMITS, make_driver

SEEDS = (1, 2, 3)


def _record() -> ServoRecord:
    spec = ServoSpec(3, "XL330-M288", role="r3")
    return ServoRecord(spec, spec.model_info, ThermalTrend(30.0), 70)


def _mutate(rec: ServoRecord, rng: random.Random) -> str:
    """Change one field of the record (any of them, by its current type); returns its name."""
    names = [f.name for f in dataclasses.fields(ServoRecord) if not f.name.startswith("_")]
    name = rng.choice(names)
    value = getattr(rec, name)
    if name == "spec":
        new: object = ServoSpec(3, "XL330-M288", role="r3", max_position_tick=rng.randint(3000, 4095))
    elif name == "info":
        new = model_by_name(rng.choice(["XL330-M288", "XL430-W250", "XM430-W350"]))
    elif name == "faults":
        rec.faults.symmetric_difference_update({rng.choice(list(FaultKind))})  # in place, as the policy does
        return name
    elif name == "hardware_error":
        new = HardwareErrorBits(rng.choice([0, 1, 4, 8, 32]))
    elif name in ("thermal", "reboots"):
        return name  # not part of the state
    elif isinstance(value, bool) or name in ("moving", "torque_on", "missing", "stale", "derated", "latched"):
        new = rng.choice([True, False, None]) if name == "moving" else rng.random() < 0.5
    elif name in ("voltage_v", "backoff_scale", "seconds_to_limit") or name.endswith("_s"):
        new = rng.choice([None, rng.uniform(0, 100)]) if value is None or name.endswith("_s") else rng.uniform(0, 1)
    else:
        new = (
            rng.choice([None, rng.randint(-2000, 4000)])
            if value is None or name.endswith("_raw")
            else rng.randint(0, 4000)
        )
    setattr(rec, name, new)
    return name


@pytest.mark.parametrize("seed", SEEDS)
def test_cached_freeze_equals_the_full_freeze_whatever_changes(seed: int) -> None:
    rng = random.Random(seed)
    rec = _record()
    states = []
    for _ in range(3000):
        for _ in range(rng.choice([0, 1, 1, 2])):
            _mutate(rec, rng)
        if rng.random() < 0.5:  # the common cycle: only the position, its time and the goal move
            rec.position_tick, rec.position_t_s = rng.randint(0, 4095), rng.uniform(0, 10)
            rec.goal_tick = rng.randint(0, 4095)
        got, want = rec.freeze(), rec.freeze_full()
        assert got == want
        assert dataclasses.asdict(got) == dataclasses.asdict(want)
        with pytest.raises(dataclasses.FrozenInstanceError):
            got.position_tick = 1  # type: ignore[misc]
        states.append((got, want))
    assert all(a == b for a, b in states)  # an earlier state never changed under a later freeze


@pytest.mark.parametrize("seed", SEEDS)
def test_lazy_freeze_builds_the_full_freeze_whatever_changes(seed: int) -> None:
    """`freeze_lazy` alone (its own cache, no `freeze` in between) against `freeze_full`."""
    rng = random.Random(seed)
    rec = _record()
    kept = []
    for _ in range(3000):
        for _ in range(rng.choice([0, 1, 1, 2])):
            _mutate(rec, rng)
        if rng.random() < 0.5:
            rec.position_tick, rec.position_t_s = rng.randint(0, 4095), rng.uniform(0, 10)
            rec.goal_tick = rng.randint(0, 4095)
        lazy = rec.freeze_lazy()  # a state, or a capture built into one on first access
        want = rec.freeze_full()
        if isinstance(lazy, tuple) and rng.random() < 0.5:
            kept.append((lazy, want))  # built later, after more mutations
            continue
        got = build_state(lazy) if isinstance(lazy, tuple) else lazy
        assert got == want and dataclasses.asdict(got) == dataclasses.asdict(want)
    assert kept and all(build_state(c) == w for c, w in kept)


def _check_goals_reference(goals_tick: Mapping[int, int], specs: Mapping[int, ServoSpec]) -> dict[int, int]:
    """`check_goals` before its fast path (the full checks for every goal)."""
    if not isinstance(goals_tick, Mapping):
        raise GoalRejectedError(None, goals_tick, f"goals must be a mapping servo id -> tick, got {type(goals_tick)}")
    out: dict[int, int] = {}
    for sid, goal in goals_tick.items():
        spec = specs.get(sid) if isinstance(sid, int) and not isinstance(sid, bool) else None
        if spec is None:
            raise GoalRejectedError(sid, goal, f"goal for unknown servo id {sid!r}; configured: {list(specs)}")
        if isinstance(goal, float) and not math.isfinite(goal):
            raise GoalRejectedError(sid, goal, f"{spec.label}: goal {goal!r} is not finite; nothing sent")
        if isinstance(goal, bool):
            raise GoalRejectedError(sid, goal, f"{spec.label}: goal {goal!r} is a bool, expected int ticks")
        try:
            tick = operator.index(goal)
        except TypeError:
            raise GoalRejectedError(
                sid, goal, f"{spec.label}: goal {goal!r} is not an integer tick (round it first); nothing sent"
            ) from None
        lo, hi = spec.min_position_tick, spec.max_position_tick
        if not lo <= tick <= hi:
            raise GoalRejectedError(
                sid, goal, f"{spec.label}: goal {tick} outside its limits {lo}..{hi} ticks; nothing sent"
            )
        out[sid] = tick
    return out


def _outcome(fn, goals, specs):  # type: ignore[no-untyped-def]
    try:
        out = fn(goals, specs)
    except GoalRejectedError as err:
        return ("rejected", str(err), err.servo_id)
    return ("ok", out, [type(v) for v in out.values()])


@pytest.mark.parametrize("seed", SEEDS)
def test_goal_check_fast_path_accepts_and_refuses_as_the_full_checks(seed: int) -> None:
    rng = random.Random(seed)
    specs = {
        i: ServoSpec(i, "XL330-M288", min_position_tick=1000 + 10 * i, max_position_tick=3000 - 10 * i)
        for i in range(1, 7)
    }
    odd = [True, False, 2048.0, 2048.5, float("nan"), float("inf"), np.int64(2048), np.int32(5000), "2048", None]
    for _ in range(3000):
        goals: dict = {}  # type: ignore[type-arg]
        for sid in rng.sample(range(0, 9), rng.randint(0, 6)):
            key = sid if rng.random() > 0.05 else rng.choice([True, np.int64(sid), float(sid)])
            goals[key] = rng.randint(900, 3100) if rng.random() > 0.1 else rng.choice(odd)
        assert _outcome(check_goals, goals, specs) == _outcome(_check_goals_reference, goals, specs), goals


class StraightDriver(Driver):
    """The driver's per-cycle paths as they were before they were made cheap (the reference)."""

    def validate_goals(self, goals_tick: Mapping[int, int]) -> dict[int, int]:
        return _check_goals_reference(goals_tick, self._specs)

    def _goal_frame(self, goals_tick: Mapping[int, int]) -> dict[int, int] | None:
        return None  # validated, then filtered and guarded, in two passes

    def _plan_calm(self, now: float) -> None:
        return None  # every cycle the full path

    def _write_goals(self, goals: Mapping[int, int]) -> None:
        frame: dict[int, int] = {}
        for sid, goal in goals.items():
            rec = self._records[sid]
            if not rec.in_service:
                continue
            if FaultKind.LOAD_BACKOFF in rec.faults and rec.position_tick is not None:
                goal = eased_goal(goal, rec.position_tick, rec.backoff_scale, *rec.limits_tick)
            frame[sid] = self._guard(rec, goal)
        if frame:
            self.bus.sync_write(Register.GOAL_POSITION, frame)
            for sid, tick in frame.items():
                self._records[sid].goal_tick = tick

    def _read_positions(self, now: float) -> None:
        started, self._position_ids = self._position_ids, None
        if started is None:
            ids = self._readable(now)
            registers = self._position_block(now)
        else:
            ids = started
            if self._folded is not None:
                registers = POSITION + self._folded.registers
            else:
                registers = (self._sentinel_read,) if self._sentinel else POSITION
        got = self._read_group(ids, registers, fast=self.fast_sync_read, started=started is not None)
        if self.fast_sync_read and ids:
            self._check_fast_read_support(self._group_failed and len(got) == len(ids))
        lost: dict[int, int] = {}
        for sid, values in got.items():
            rec = self._records[sid]
            if registers[0] not in (SENTINEL, SENTINEL_SHORT):
                rec.position_tick = values[Register.PRESENT_POSITION]
            else:
                tick, byte = split(values[registers[0]], registers[0])
                if byte != self._witness[sid]:
                    lost[sid] = byte
                    continue
                rec.position_tick = tick
            rec.position_t_s = now
        group, self._folded = self._folded, None
        if group is not None and ids:
            self._folded_this_cycle = True
            group.due_s = now + group.period_s
            extra_bytes = len(ids) * (span(registers)[1] - span(POSITION)[1])
            group.cost_s = extra_bytes * 10.0 / max(1, int(getattr(self.bus, "baud", 1_000_000)))
            self.telemetry_reads[group.name] += 1
            self._apply_group(group, got, now)
        self._mark_results(ids, got, now)
        for sid, byte in lost.items():
            self._sentinel_lost(self._records[sid], byte, now)

    def _due_group(self, now: float) -> TelemetryGroup | None:
        late = 1.0 / self.policy.telemetry_floor_share - 1.0
        ready = [
            g
            for g in self._groups
            if g.due_s <= now
            and (
                g.due_s == float("-inf")
                or self._idle_s >= g.cost_s
                or (not (g.name == "status" and self._sentinel) and now >= g.due_s + g.period_s * late)
                or (
                    g.name == "status"
                    and self._sentinel
                    and now >= g.due_s - g.period_s + self.policy.sentinel_status_floor_s
                )
            )
        ]
        return min(ready, key=lambda g: g.due_s) if ready else None

    def _freeze(self, now: float) -> ChainSnapshot:
        snap = ChainSnapshot(
            t_s=now,
            cycle=self._cycle,
            servos={sid: rec.freeze_full() for sid, rec in self._records.items()},
            events=tuple(self._cycle_events),
            stats=self.bus.stats.copy(),
            bus_connected=self._connected,
        )
        self._last = snap
        return snap


def _wire(chain) -> list[tuple]:  # type: ignore[no-untyped-def,type-arg]
    return [(round(e.t_s, 9), e.id, e.instruction, bytes(e.params)) for e in chain.log]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("fast", [False, True])
def test_fast_and_straightforward_driver_put_the_same_bytes_on_the_wire(seed: int, fast: bool) -> None:
    rng = random.Random(seed)
    runs = []
    for cls in (Driver, StraightDriver):
        chain, plain = make_driver(ids=(1, 2, 3, 4, 5))
        driver = cls(plain.bus, list(plain._specs.values()), clock=chain.clock, fast_sync_read=fast)
        driver.configure()
        driver.torque_on()
        runs.append((chain, driver, random.Random(seed)))
    snaps: list[list[object]] = [[], []]
    for step in range(400):
        kind = rng.random()
        goals: dict = {  # type: ignore[type-arg]
            sid: rng.randint(*LIMITS.get(sid, (1024, 3072))) for sid in rng.sample(range(1, 6), rng.randint(0, 5))
        }
        if kind < 0.03:
            goals[rng.choice([1, 9])] = rng.choice([2048.5, True, 99999, "x"])  # refused whole, nothing sent
        fault = rng.random()
        for k, (chain, driver, _) in enumerate(runs):
            if fault < 0.02:
                chain.faults.inject(2, "no_reply", duration_s=0.02)
            elif fault < 0.03:
                chain.faults.inject(3, "overload", duration_s=0.01)
            elif fault < 0.04:
                chain.set_obstacle(1, 2200 if (step // 50) % 2 == 0 else None)
            try:
                snaps[k].append(driver.cycle(goals))
            except GoalRejectedError as err:
                snaps[k].append(("rejected", str(err)))
            chain.advance(DT_S)
    (chain_a, drv_a, _), (chain_b, drv_b, _) = runs
    assert _wire(chain_a) == _wire(chain_b)
    assert len(chain_a.goal_writes()) > 500
    assert snaps[0] == snaps[1]
    assert list(drv_a.events) == list(drv_b.events)
    assert any(isinstance(s, ChainSnapshot) and any(st.faults for st in s) for s in snaps[0])  # faults were seen


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("fast", [False, True])
def test_telemetry_folded_into_the_position_read_gives_the_same_states_and_reactions(seed: int, fast: bool) -> None:
    """A due motion / thermal group read in the position read's transaction (`fold_telemetry`, fewer
    transactions) and read as a group of its own: the same servo states, faults and reactions, cycle by
    cycle, under random goals, an obstacle (load back-off) and a hot servo (derate). (An Alert bit is left
    out: the folded driver then reads the status group as well, in the same cycle, where the other reads
    it instead of the due group, so their schedules differ from there by design.)"""
    rng = random.Random(seed)
    runs = []
    for fold in (True, False):
        chain, driver = make_driver(ids=(1, 2, 3, 4, 5))
        driver.fast_sync_read = fast
        driver.fold_telemetry = fold
        runs.append((chain, driver))
    for step in range(300):
        goals = {sid: rng.randint(*LIMITS.get(sid, (1024, 3072))) for sid in rng.sample(range(1, 6), 3)}
        states = []
        for chain, driver in runs:
            if step == 40:
                chain.set_obstacle(1, 2200)
            if step == 120:
                chain.set_obstacle(1, None)
                chain.servo(3).temperature_c = 66.0  # near its 70 C limit: derated
            snap = driver.cycle(goals)
            states.append((dict(snap.servos), [(e.servo_id, e.kind, e.reaction) for e in snap.events]))
            chain.advance(DT_S)
        assert states[0] == states[1], step
    (chain_f, drv_f), (chain_s, drv_s) = runs
    assert drv_f.telemetry_reads == drv_s.telemetry_reads
    assert drv_f.bus.stats.transactions < drv_s.bus.stats.transactions  # fewer transactions when folded
    assert any(e.kind == FaultKind.LOAD_BACKOFF for e in drv_f.events)
    assert any(e.kind == FaultKind.THERMAL_DERATE for e in drv_f.events)


def test_lazy_snapshot_states_are_built_once_equal_and_read_only() -> None:
    chain, driver = make_driver(ids=(1, 2, 3))
    driver.cycle({1: 2000})
    snap = driver.cycle({1: 2100, 2: 1600})
    assert isinstance(snap.servos, LazyServoStates)
    eager = {sid: rec.freeze_full() for sid, rec in driver._records.items()}
    assert dict(snap.servos) == eager and snap.servos == eager and eager == dict(snap.servos)
    assert snap[1] is snap.servos[1]  # built once, then kept
    assert list(snap.servos) == [1, 2, 3] and len(snap.servos) == 3 and 2 in snap.servos and 9 not in snap.servos
    assert snap.servos.get(9) is None and snap.positions_tick() == {s: st.position_tick for s, st in eager.items()}
    later = driver.cycle({1: 2200})
    assert dict(snap.servos) == eager  # an earlier snapshot does not move with the records
    assert later[1].goal_tick == 2200 and snap[1].goal_tick == 2100
    with pytest.raises(TypeError):
        snap.servos[1] = snap[1]  # type: ignore[index]


@pytest.mark.parametrize("seed", SEEDS)
def test_bus_stats_copy_equals_the_dataclass_built_copy(seed: int) -> None:
    rng = random.Random(seed)
    stats = BusStats()
    for _ in range(200):
        setattr(stats, rng.choice([f.name for f in dataclasses.fields(BusStats)]), rng.randint(0, 10**6))
        got, want = stats.copy(), BusCounters(**vars(stats))
        assert type(got) is BusCounters and got == want and dataclasses.asdict(got) == dataclasses.asdict(want)
        stats.transactions += 1
        assert got == want  # a copy, not a view
        with pytest.raises(dataclasses.FrozenInstanceError):
            got.timeouts = 0  # type: ignore[misc]


_SLOW_FIELDS = tuple(
    f.name
    for f in dataclasses.fields(ServoState)
    if f.name not in ("position_tick", "position_t_s", "goal_tick", "stale")
)


@pytest.mark.parametrize("seed", SEEDS)
def test_peeking_a_lazy_snapshot_gives_the_built_states_slow_fields_and_goal(seed: int) -> None:
    """`peek_state` on the driver's snapshots (captures and states alike, peeked before or after the states
    are built, and on earlier snapshots after the records moved on) equals the states' own fields."""
    rng = random.Random(seed)
    chain, driver = make_driver(ids=(1, 2, 3))
    kept: list[ChainSnapshot] = []
    captures = 0
    for step in range(150):
        goals = {sid: rng.randint(1500, 2500) for sid in (1, 2, 3) if rng.random() < 0.7}
        if step % 40 == 20:
            chain.servo(rng.choice((1, 2, 3))).temperature_c = rng.choice([40.0, 66.0])
        snap = driver.cycle(goals)
        chain.advance(DT_S)
        captures += sum(type(item) is tuple for item in snap.servos._items.values())  # type: ignore[attr-defined]
        if rng.random() < 0.3:
            kept.append(snap)
            continue
        for sid in (1, 2, 3):
            if rng.random() < 0.3:
                snap.servos[sid]  # built first, then peeked
            _same_as_built(snap, sid)
        assert peek_state(snap.servos, 9) is None
    assert captures > 100  # most servos were captures, not states
    for snap in kept:  # peeked after later cycles moved the records on
        for sid in (1, 2, 3):
            _same_as_built(snap, sid)


def _same_as_built(snap: ChainSnapshot, sid: int) -> None:
    peeked = peek_state(snap.servos, sid)
    assert peeked is not None
    state = snap.servos[sid]
    assert peeked[1] == state.goal_tick
    assert all(getattr(peeked[0], name) == getattr(state, name) for name in _SLOW_FIELDS)
    plain = peek_state(dict(snap.servos), sid)  # any other mapping: the state itself
    assert plain is not None and plain[0] is state and plain[1] == state.goal_tick
