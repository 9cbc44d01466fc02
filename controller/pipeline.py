"""One control frame through the whole chain: AU frame -> muscle model -> actuator targets -> calibration
-> goals -> twin gate -> driver.

`Pipeline.step` runs one frame and returns a `FrameTrace` a user can inspect: AUs in, targets, goals,
verdict and reasons, bytes written, stage timings. Nothing reaches the driver without a gate verdict, and a
frame whose input is invalid raises before anything is computed or sent.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from servoface.calibration import HeadCalibration
from servoface.controller.errors import FrameError
from servoface.controller.frame import AUFrame
from servoface.controller.pipeline_ahead import Ahead, Speculation
from servoface.controller.telemetry import StrainedHealth
from servoface.hardware.driver import Driver
from servoface.hardware.snapshot import ChainSnapshot, peek_state
from servoface.sim.errors import SimError
from servoface.sim.face_model import FaceModel
from servoface.sim.gate import GateConfig, ServoHealth, TwinGate, Verdict
from servoface.sim.head import Head

PACE_MAX_SHARE = 0.25  # a frame at most this share of a period early is held to its slot (`_slot_deficit`)
PAY_BACK_SHARE = 0.1  # a held frame more than this share early is sent at once if that accepts cleanly (`_pay_back`)
PLAN_HISTORY = 16  # a caller faster than the rate: its next check is planned from this many last elapsed times:
PLAN_SHORT_OF = 4  # the shortest of the last 4 (a clean accept holds for any longer time, `Speculation.holds_for`)
PLAN_LONG_QUANTILE = 0.8  # and this quantile of them (a clip, used when the step waits for it: `_reach_plan`)
PLAN_SNAP_S = 0.1e-3  # a long plan this little short of the last check's elapsed time is moved to it (`_plans_s`)
PLAN_WAIT_MAX_S = 1.5e-3  # at most this long a spin for a planned elapsed time (`_reach_plan`; a clip check ~2-3 ms)
KEY_SLACK_S = 20e-6  # a check this much after a speculation's plan compares rate keys (later: caps have grown)


@dataclass(frozen=True)
class FrameTrace:
    """What happened to one frame (all dicts are copies; safe to keep)."""

    index: int
    t_s: float
    aus: dict[str, float]
    targets: dict[str, float]  # role -> deg / mm, as the muscle model asked
    target_clamps: tuple[str, ...]  # reasons: targets outside the calibrated range, clamped into it
    goals_requested: dict[int, int]  # id -> tick, from the (clamped) targets
    verdict: str  # accept / clip / reject (clip also when only target clamps fired)
    checks: tuple[str, ...]
    reasons: tuple[str, ...]
    goals_sent: dict[int, int]  # what the gate let through (== what the driver was given)
    bytes_written: int  # bytes the bus wrote during this frame (0 without a driver)
    timings_ms: dict[str, float] = field(default_factory=dict)
    late_s: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "t_s": round(self.t_s, 6),
            "aus": {k: round(v, 4) for k, v in self.aus.items()},
            "targets": {k: round(v, 3) for k, v in self.targets.items()},
            "target_clamps": list(self.target_clamps),
            "goals_requested": {str(k): v for k, v in self.goals_requested.items()},
            "verdict": self.verdict,
            "checks": list(self.checks),
            "reasons": list(self.reasons),
            "goals_sent": {str(k): v for k, v in self.goals_sent.items()},
            "bytes_written": self.bytes_written,
            "timings_ms": {k: round(v, 4) for k, v in self.timings_ms.items()},
            "late_s": round(self.late_s, 6),
        }


class Pipeline:
    """The per-frame chain for one head. ``driver`` may be None (offline: the gate still runs).

    ``last_goals_tick`` starts at the calibration's neutral goals, or at the servos' present positions when
    the caller pins them (`pin_to`), so the first frame is rate-checked against where the head really is.
    """

    def __init__(
        self,
        head: Head,
        calibration: HeadCalibration,
        *,
        driver: Driver | None = None,
        rate_hz: float = 50.0,
        gate_config: GateConfig | None = None,
        face: FaceModel | None = None,
        gate: TwinGate | None = None,
        temperature_limits_c: Mapping[int, float] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.head = head
        self.clock = clock  # when goals went on the wire (per-time caps); tests may pass the emulator's clock
        self.calibration = calibration
        self.driver = driver
        self.rate_hz = float(rate_hz)
        self.face = face or FaceModel(head)
        self.gate = gate or TwinGate(head, calibration, 1.0 / self.rate_hz, gate_config, face_model=self.face)
        missing = sorted(set(head.roles) - set(calibration.roles))
        if missing:
            raise SimError(f"calibration for head {head.name!r} lacks servo role(s) {missing}")
        self._servos = [calibration[r] for r in head.roles]
        self._lo = np.array([s.min_target for s in self._servos])
        self._hi = np.array([s.max_target for s in self._servos])
        self._neutral = [float(s.neutral_target) for s in self._servos]  # a curve inverse each: compute once
        self._set_columns()
        self.last_goals_tick: dict[int, int] = calibration.neutral_goals()
        self.temperature_limits_c = dict(temperature_limits_c or {})
        self._ids = frozenset(s.servo_id for s in self._servos)
        self._strained = StrainedHealth(self._ids)
        self.last_snapshot: ChainSnapshot | None = None
        self.last_cycle_s: float | None = None  # clock() of the last driver cycle (pacing)
        self.last_write_s: float | None = None  # clock() when the last goals went on the wire
        self.last_write_began_s: float | None = None  # clock() when that write began (its `cycle_start` called)
        # where that write's slot began: the time it was held to (a held frame), else when it began; the next
        # held write is held to a period after it (`_slot`), so sleep overshoots do not add up either
        self.last_slot_start_s: float | None = None
        # the elapsed time a held next frame is checked for: a period less the time from the last write's
        # slot start to its end (None: a whole period), so that held writes start a period apart (`_slot`)
        self._slot_s: float | None = None
        self._interval_s: float | None = None  # between the last two writes (plans the speculation)
        self._short_run = 0  # writes in a row that came well within a period of the one before
        self._checked_s: float | None = None  # the elapsed time the last check was made for
        self._last_clipped = False  # the last frame's verdict was not a clean accept (see `_plans_s`)
        self._elapsed_s: deque[float] = deque(maxlen=PLAN_HISTORY)  # the last checks' elapsed times (`_plans_s`)
        self.per_time_caps = True  # False: the gate's per-frame caps only (deterministic replays in tests)
        self._index = 0
        self._ahead: Ahead | None = None  # the next frame, computed during this one's wait (step(next_frame=))
        self._solved: tuple[tuple[dict[str, float], int, int], tuple[Any, ...]] | None = None  # see _solve
        self.pace_writes = True  # hold a frame a little early to its slot, checked for a whole period (`_slot_deficit`)
        # the next frame's gate check during the wait too (else only its muscle model and calibration): saves
        # wall time, but costs a second check whenever new telemetry or timing voids it (`play_timeline`,
        # paced at the rate with time to spare, turns it off: one check per frame)
        self.speculate_gate = True

    # -- state ------------------------------------------------------------------------------------
    def pin_to(self, goals_tick: Mapping[int, int]) -> None:
        """Take ``goals_tick`` (e.g. present positions after torque-on) as the last safe command."""
        unknown = sorted(set(goals_tick) - self._ids)
        if unknown:
            raise SimError(f"pin_to: servo id(s) {unknown} are not in head {self.head.name!r}")
        self.last_goals_tick = {**self.last_goals_tick, **{int(k): int(v) for k, v in goals_tick.items()}}

    def use_calibration(self, calibration: HeadCalibration, gate: TwinGate) -> None:
        """Drive with ``calibration`` and its ``gate`` (built for it) from the next frame on. Call between
        frames (on the loop thread, or with the loop paused): everything a frame reads of the calibration is
        replaced at once, the speculative next frame is dropped, and the last command is clamped into the
        new limits (the next frame is rate-checked from there)."""
        missing = sorted(set(self.head.roles) - set(calibration.roles))
        if missing:
            raise SimError(f"calibration for head {self.head.name!r} lacks servo role(s) {missing}")
        servos = [calibration[r] for r in self.head.roles]
        ids = frozenset(s.servo_id for s in servos)
        if ids != self._ids:
            raise SimError(f"calibration servo ids {sorted(ids)} differ from the running {sorted(self._ids)}")
        lo_hi = calibration.position_limits_tick()
        last = {sid: min(max(int(t), lo_hi[sid][0]), lo_hi[sid][1]) for sid, t in self.last_goals_tick.items()}
        lo = np.array([s.min_target for s in servos])
        hi = np.array([s.max_target for s in servos])
        neutral = [float(s.neutral_target) for s in servos]
        self._ahead = None
        self._solved = None  # the last solve was through the old calibration
        self.calibration, self.gate = calibration, gate
        self._servos, self._lo, self._hi, self._neutral = servos, lo, hi, neutral
        self.last_goals_tick = last
        self._set_columns()
        self.gate.reset()

    def _set_columns(self) -> None:
        """What a frame reads of the calibration in array form (head role order)."""
        self._roles = [s.role for s in self._servos]
        self._goal_ids = [s.servo_id for s in self._servos]
        self._cols = self.calibration.columns(self._roles)
        self._clamp_tol = 1e-6 * np.maximum(1.0, self._hi - self._lo)

    # -- one frame --------------------------------------------------------------------------------
    def targets_for(self, aus: Mapping[str, float]) -> dict[str, float]:
        """Actuator targets (role -> deg/mm) the muscle model asks for (validates the AUs)."""
        return self.face.actuator_targets(aus)

    def clamp_targets(self, targets: Mapping[str, float]) -> tuple[dict[str, float], list[str]]:
        """Targets clamped into each servo's calibrated range, with one reason per clamp."""
        clamped, reasons = self._clamp_array(targets)
        return dict(zip(self._roles, clamped.tolist(), strict=True)), reasons

    def _clamp_array(self, targets: Mapping[str, float]) -> tuple[np.ndarray, list[str]]:
        """`clamp_targets` as an array in head role order (the frame path: no dict until the trace)."""
        get = targets.get
        values = np.array([float(get(r, n)) for r, n in zip(self._roles, self._neutral, strict=True)])
        if not np.logical_and.reduce(np.isfinite(values)):  # (ufunc reductions: no `all` / `any` wrappers)
            bad = [s.role for s, v in zip(self._servos, values, strict=True) if not np.isfinite(v)]
            raise FrameError(f"muscle model produced non-finite targets for {bad}")
        clamped = np.minimum(np.maximum(values, self._lo), self._hi)  # np.clip's arithmetic, without its wrappers
        off = np.abs(values - clamped) > self._clamp_tol
        if not np.logical_or.reduce(off):
            return clamped, []
        reasons = [
            f"[target] {s.role}: {values[i]:.2f} {s.unit} outside the calibrated {self._lo[i]:.2f}.."
            f"{self._hi[i]:.2f}, clamped"
            for i in np.flatnonzero(off).tolist()
            for s in (self._servos[i],)
        ]
        return clamped, reasons

    def step(
        self,
        frame: AUFrame | Mapping[str, float],
        t_s: float | None = None,
        late_s: float = 0.0,
        next_frame: AUFrame | Mapping[str, float] | None = None,
    ) -> FrameTrace:
        """Run one frame. Raises (FrameError / sim errors) on invalid input, before anything is sent.

        ``next_frame``: the AUs the next call will most likely bring; with a driver, its muscle model,
        calibration and a speculative gate check run while this frame's replies are on the wire, and the next
        step uses them only if they are exactly what it would compute (`servoface.controller.pipeline_ahead`).
        A frame that comes a little less than a frame period after the last write is checked with the caps of
        a whole period and sent once the period is over (`_slot_deficit`: a paced loop's jitter would otherwise
        shrink the caps and void that speculation); the same AUs as the last frame are not solved again
        (`_solve`).
        """
        timings: dict[str, float] = {}
        t0 = time.perf_counter()
        aus = dict(frame.aus) if isinstance(frame, AUFrame) else dict(frame)
        t = frame.t_s if isinstance(frame, AUFrame) and t_s is None else float(t_s or 0.0)
        ahead, self._ahead = self._ahead, None
        if ahead is not None and ahead.aus != aus:
            ahead = None
        if ahead is not None:
            targets, clamped, clamp_reasons = ahead.targets, ahead.clamped, list(ahead.clamp_reasons)
            requested = dict(ahead.requested)
            timings.update(ahead.timings_ms)
        else:
            targets, clamped, reasons, requested = self._solve(aus, timings)
            clamp_reasons = list(reasons)
        deficit_s = self._slot_deficit()
        held = deficit_s is not None
        t2 = time.perf_counter()
        health = self._health()
        elapsed_s = (
            None
            if self.driver is None or self.last_write_s is None or not self.per_time_caps
            else self._slot()
            if held
            else self.clock() - self.last_write_s
        )  # since the last goals went on the wire (a held frame: when they will): caps hold per second
        # a speculative verdict is used when its inputs are exactly this check's: the same AUs, last command,
        # health and gate memory (`Ahead.matches`), and either it is a clean accept checked for a planned
        # elapsed time this one reaches (`Speculation.holds_for`) or this elapsed time makes exactly the rate
        # caps it was checked with (`TwinGate.rate_key`: per-frame caps, or a planned interval's)
        spec = None
        if elapsed_s is not None:
            self._elapsed_s.append(elapsed_s)
        # (an Ahead without speculations has nothing to match: no copy of the gate's memory for it)
        if (
            ahead is not None
            and ahead.speculations
            and ahead.matches(self.last_goals_tick, health, self.gate.step_state())
        ):
            for s in ahead.speculations:
                elapsed_s = self._reach_plan(s.plan_s, elapsed_s)
                if s.holds_for(elapsed_s):
                    spec = s
                    break
                near = elapsed_s is None or s.plan_s is None or elapsed_s <= s.plan_s + KEY_SLACK_S
                if near and self.gate.rate_key(self.last_goals_tick, health, elapsed_s) == s.rate_key:
                    spec = s
                    break
        self._checked_s = elapsed_s  # (after any wait for a plan; see `_plans_s`)
        if spec is not None and ahead is not None:
            verdict = spec.verdict
            self.gate.remember_check(verdict, self.last_goals_tick, health, elapsed_s)  # as the check would
            timings["ahead_ms"] = sum(ahead.timings_ms.values())
        else:
            verdict = self.gate.check(requested, self.last_goals_tick, health, elapsed_s=elapsed_s)
            timings["gate_ms"] = (time.perf_counter() - t2) * 1e3
        if deficit_s is not None and deficit_s > PAY_BACK_SHARE * self.gate.frame_period_s and _clean(verdict):
            t_pay = time.perf_counter()
            paid = self._pay_back(requested, health)
            timings["gate_ms" if "gate_ms" in timings else "ahead_ms"] += (time.perf_counter() - t_pay) * 1e3
            if paid is not None:
                verdict, elapsed_s = paid
                held = False
                self._checked_s = self._elapsed_s[-1] = elapsed_s
        self._last_clipped = not _clean(verdict)
        sent = dict(verdict.goals_tick)
        written = 0
        slot_start_s = None
        if held:  # checked for its slot: the goals leave no earlier than that after the last ones
            slot_start_s = self._hold_to_slot()
        t3 = time.perf_counter()
        if self.driver is not None:
            before = self.driver.bus.stats.bytes_written
            began_s = self.clock()
            self.driver.cycle_start(sent)
            now_s = self.clock()  # after: the goals are on the wire by now (conservative)
            period_s = self.gate.frame_period_s  # a held next frame starts its write a period after this one's:
            slot_start_s = began_s if slot_start_s is None else min(slot_start_s, began_s)
            self._slot_s = period_s - min(max(0.0, now_s - slot_start_s), PACE_MAX_SHARE * period_s)  # `_slot`
            self.last_write_began_s, self.last_slot_start_s = began_s, slot_start_s
            interval = None if self.last_write_s is None else now_s - self.last_write_s
            short = interval is not None and interval < self.gate.frame_period_s * (1.0 - PACE_MAX_SHARE)
            self._short_run = self._short_run + 1 if short else 0
            self._interval_s = interval
            self.last_write_s = now_s
            if next_frame is not None:  # while the replies are on the wire
                self._ahead = self._prepare(next_frame, sent, health)
            self.last_snapshot = self.driver.cycle_finish()
            self.last_cycle_s = self.clock()
            written = self.driver.bus.stats.bytes_written - before
        t4 = time.perf_counter()
        timings["bus_ms"] = (t4 - t3) * 1e3
        timings["total_ms"] = (t4 - t0) * 1e3
        self.last_goals_tick = sent
        if self.driver is not None and self.last_snapshot is not None:
            self._sync_with_driver(self.last_snapshot)
        kind = verdict.kind
        if kind == "accept" and clamp_reasons:
            kind = "clip"
        checks = tuple(dict.fromkeys((["target"] if clamp_reasons else []) + list(verdict.checks)))
        trace = FrameTrace(
            index=self._index,
            t_s=t,
            aus=aus,
            targets=dict(targets),
            target_clamps=tuple(clamp_reasons),
            goals_requested=dict(requested),
            verdict=kind,
            checks=checks,
            reasons=tuple(clamp_reasons + verdict.reasons()),
            goals_sent=sent,
            bytes_written=written,
            timings_ms=timings,
            late_s=late_s,
        )
        self._index += 1
        return trace

    def _solve(
        self, aus: dict[str, float], timings: dict[str, float]
    ) -> tuple[dict[str, float], dict[str, float], tuple[str, ...], dict[int, int]]:
        """Muscle model + calibration for ``aus``: (targets, clamped targets, clamp reasons, goals), with
        their times in ``timings``. The last result is kept: the same AUs again (a held expression, a
        speculative next frame that equals this one) are not solved again (the muscle model and the
        calibration are pure functions of the AUs). Invalid AUs raise, as the muscle model does."""
        t0 = time.perf_counter()
        key = (aus, id(self.face), id(self.calibration))
        last = self._solved
        if last is not None and last[0] == key:
            timings["muscle_ms"] = (time.perf_counter() - t0) * 1e3
            timings["calibration_ms"] = 0.0
            targets, clamped, reasons, requested = last[1]
            return dict(targets), dict(clamped), reasons, dict(requested)
        targets = self.targets_for(aus)
        t1 = time.perf_counter()
        timings["muscle_ms"] = (t1 - t0) * 1e3
        clamped_arr, reasons = self._clamp_array(targets)
        requested = dict(
            zip(self._goal_ids, self.calibration.column_goals(self._cols, clamped_arr).tolist(), strict=True)
        )
        clamped = dict(zip(self._roles, clamped_arr.tolist(), strict=True))
        timings["calibration_ms"] = (time.perf_counter() - t1) * 1e3
        result = (targets, clamped, tuple(reasons), requested)
        self._solved = ((dict(aus), id(self.face), id(self.calibration)), result)
        return dict(targets), dict(clamped), result[2], dict(requested)

    def _slot(self) -> float:
        """The elapsed time a held frame is checked for and sent after: one period from where the last write's
        slot began (`last_slot_start_s`: the time it was held to, or when it began), counted from when it
        ended (`last_write_s`, taken after it to be safe): a period less that write's own time and any
        oversleep of its hold (at most `PACE_MAX_SHARE` of a period less; a whole period before any write)."""
        return self.gate.frame_period_s if self._slot_s is None else self._slot_s

    def _slot_deficit(self) -> float | None:
        """How early this frame is for its slot, if it is held to it (else None): it comes a little less
        than `_slot` after the last goals went on the wire (a paced loop) — at most `PACE_MAX_SHARE` of a
        period early. The gate then checks it with the caps of that elapsed time (as the speculative check
        during the last wait did, `_plans_s`, so that verdict is used instead of a second check), and
        `_hold_to_slot` sends it no earlier than that after the last write: the check's time is spent inside
        the period, not added to it, and as the slot is a period from where the last one's began, held writes
        begin on a grid a period apart — they do not drift later by a check, a write or a sleep's overshoot a
        frame (a slot of a whole period from the end of the last write let a paced loop's writes drift ~0.35
        ms a frame, until `_pay_back` checked a frame a second time to catch up: one frame in three). A late
        frame is checked for the time that has passed; the next one early by more than `PAY_BACK_SHARE` of a
        period and clean goes at once (`_pay_back`). The caps are never for more time than passes from the
        end of one write to the start of the next (tests/controller/test_pipeline_slot.py). A caller stepping
        faster than the rate is not held (its caps shrink with the time instead, and a late frame of it is not held
        either: its speculations were planned for its own short intervals, `_plans_s`), nor one without a
        driver, with `pace_writes` off, or on a clock that is not the real monotonic one (a test's manual
        clock does not move while we sleep: its caller owns time)."""
        if self.driver is None or self.last_write_s is None or not self.per_time_caps or not self.pace_writes:
            return None
        if self._short_run >= 2 or self.clock is not time.monotonic:
            return None
        deficit_s = self._slot() - (self.clock() - self.last_write_s)
        return deficit_s if 0 < deficit_s <= PACE_MAX_SHARE * self.gate.frame_period_s else None

    def _pay_back(
        self, requested: dict[int, int], health: dict[int, ServoHealth] | None
    ) -> tuple[Verdict, float] | None:
        """A held frame more than `PAY_BACK_SHARE` of a period early whose whole-period verdict is a clean
        accept: checked again for the time that has really passed; if that accepts cleanly too (the same
        goals), it is sent at once with that verdict and elapsed time, which brings the paced writes back
        towards the start of their slots on a frame whose caps do not matter. Else None, and the gate's
        memory is as the whole-period check left it (the frame is held). Without this, the drift ends only
        when a frame comes more than `PACE_MAX_SHARE` early, and is checked with shrunk caps whatever it
        asks. (The second check is cheap: the command's state checks are remembered by the gate.)"""
        last_write_s = self.last_write_s
        if last_write_s is None:
            return None
        state = self.gate.step_state()
        elapsed_s = self.clock() - last_write_s
        verdict = self.gate.check(requested, self.last_goals_tick, health, elapsed_s=elapsed_s)
        if _clean(verdict):
            return verdict, elapsed_s
        self.gate.restore_step_state(state)
        return None

    def _hold_to_slot(self) -> float | None:
        """Sleep until `_slot` has passed since the last write (a held frame, `_slot_deficit`: its caps were
        those of that elapsed time, never more time than really passes before its goals leave); returns the
        time it held to (None without a last write)."""
        last_write_s = self.last_write_s
        if last_write_s is None:
            return None
        slot_s = self._slot()
        while (deficit_s := slot_s - (self.clock() - last_write_s)) > 0:
            time.sleep(deficit_s)  # (never ends early on a monotonic clock; re-checked all the same)
        return last_write_s + slot_s

    def _health(self) -> dict[int, ServoHealth] | None:
        if self.last_snapshot is None:
            return None
        return self._strained(self.last_snapshot, self.temperature_limits_c, self.gate.config.health)

    def _prepare(
        self, frame: AUFrame | Mapping[str, float], sent: dict[int, int], health: dict[int, ServoHealth] | None
    ) -> Ahead | None:
        """Frame N+1 during frame N's wait (see `servoface.controller.pipeline_ahead`). Invalid AUs give
        None: the error is raised when that frame is stepped, before anything is sent."""
        aus = dict(frame.aus) if isinstance(frame, AUFrame) else dict(frame)
        solved: dict[str, float] = {}
        try:
            targets, clamped, reasons, requested = self._solve(aus, solved)
        except Exception:  # noqa: BLE001 - re-raised by the step of that frame, where it belongs
            return None
        if not self.speculate_gate:  # the solve only; the step checks (`Ahead.matches` is False)
            return Ahead(aus, targets, clamped, tuple(reasons), requested, solved, dict(sent),
                         None if health is None else dict(health), None)  # fmt: skip
        t2 = time.perf_counter()
        gate = self.gate
        before = gate.step_state()
        specs: list[Speculation] = []
        for plan_s in self._plans_s():
            try:
                key = gate.rate_key(sent, health, plan_s)
                verdict = gate.check(requested, sent, health, elapsed_s=plan_s)
            except Exception:  # noqa: BLE001 - the step checks afresh (and raises there)
                specs.clear()
                break
            finally:
                gate.restore_step_state(before)  # never left in a speculative state
            specs.append(Speculation(verdict, key, plan_s))
            if specs[-1].clean_accept():  # good for any later time: no later plan needed
                break
        timings = {**solved, "gate_ms": (time.perf_counter() - t2) * 1e3}
        return Ahead(aus, targets, clamped, tuple(reasons), requested, timings, dict(sent),
                     None if health is None else dict(health), before, tuple(specs))  # fmt: skip

    def _plans_s(self) -> tuple[float | None, ...]:
        """The elapsed times the speculative checks of the next frame assume, in order: for a paced caller,
        `_slot` (what a held next frame is checked for; (None,), the per-frame caps, without per-time caps
        or pacing); for one stepping faster than the rate (frames back to
        back, the last two intervals well under a period), the shortest elapsed time of the last
        `PLAN_HISTORY` checks — the next check most likely comes at least that late, and a clean accept
        checked for it holds for any later time (`Speculation.holds_for`) — then, for a frame that does not
        accept cleanly there, the longest of them (at most `PLAN_WAIT_MAX_S` later): a step that comes before
        it waits for it (`_reach_plan`), so that its caps are the planned ones."""
        interval = self._interval_s
        if not self.per_time_caps:
            return (None,)
        if interval is None or self._short_run < 2 or not self._elapsed_s:
            # (one short: a paced loop's catch-up after a late frame, its next comes a period later)
            return (self._slot_s,) if self.pace_writes and self.clock is time.monotonic else (None,)
        recent = sorted(self._elapsed_s)
        short_s = min(list(self._elapsed_s)[-PLAN_SHORT_OF:])
        if short_s >= self.gate.frame_period_s * (1.0 - PACE_MAX_SHARE):
            return (self._slot_s,) if self.pace_writes and self.clock is time.monotonic else (None,)
        long_s = min(recent[int(PLAN_LONG_QUANTILE * (len(recent) - 1))], short_s + PLAN_WAIT_MAX_S)
        last_s = self._checked_s  # the last check's elapsed time (its f_last): a plan a hair short of it
        if last_s is not None and long_s < last_s < long_s + PLAN_SNAP_S:  # would scale the last step by just
            long_s = last_s  # under 1 (truncated a tick lower) and a wait a hair longer to 1: planned at it
        if long_s <= short_s:
            return (short_s,)
        return (long_s,) if self._last_clipped else (short_s, long_s)

    def _reach_plan(self, plan_s: float | None, elapsed_s: float | None) -> float | None:
        """A speculation checked for a planned elapsed time (`_plans_s`): a frame a little early spins to the
        planned time (at most `PLAN_WAIT_MAX_S`, real clock only), so that its caps can be the planned
        ones. Returns the elapsed time now."""
        last_write_s = self.last_write_s
        if plan_s is None or elapsed_s is None or last_write_s is None:
            return elapsed_s
        if elapsed_s < plan_s and plan_s - elapsed_s <= PLAN_WAIT_MAX_S and self.clock is time.monotonic:
            while self.clock() - last_write_s < plan_s:
                pass
            elapsed_s = self.clock() - last_write_s
        return elapsed_s

    def _sync_with_driver(self, snapshot: ChainSnapshot) -> None:
        """Take the goal the driver really left on a servo in service as the last command when it differs
        from what the gate passed: a servo recovered after a fault is re-pinned where it stands, a load
        back-off eases its goal. The next frame is then rate-checked from there, not from a goal the servo
        never got (which would let the gate pass a jump far beyond its step cap)."""
        changed: dict[int, int] = {}
        servos, last = snapshot.servos, self.last_goals_tick
        for sid in self._ids:
            peeked = peek_state(servos, sid)  # torque and goal only: no state built
            if peeked is None or not peeked[0].torque_on or peeked[1] is None:
                continue
            goal_tick = int(peeked[1])
            if goal_tick != last.get(sid):
                changed[sid] = goal_tick
        if changed:
            self.last_goals_tick = {**self.last_goals_tick, **changed}
            self.gate.reset()  # its step memory no longer matches the wire: start from rest

    def hold(self) -> ChainSnapshot | None:
        """Re-send the last safe command (e.g. while nothing plays) and refresh telemetry."""
        if self.driver is None:
            return None
        self.last_snapshot = self.driver.cycle(self.last_goals_tick)
        self.last_cycle_s = self.last_write_s = self.clock()
        self._slot_s = None
        self.gate.reset()  # the servos got a zero step: the next frame starts from rest (accel cap)
        return self.last_snapshot


def _clean(verdict: Verdict) -> bool:
    """A clean accept: no finding but health (every rate check passed, no state check fired)."""
    return verdict.kind == "accept" and all(f.check == "health" for f in verdict.findings)
