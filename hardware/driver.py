"""`Driver`: owns one bus from one thread; one `cycle()` per control frame.

A cycle: validate goals (refuse the whole frame on any bad goal: nothing sent) -> one Sync Write of Goal
Position to the servos in service -> one (Fast) Sync Read of Present Position (every reply's Alert bit
is kept: an alarm is seen the cycle it happens), through the position sentinel where it verified at
`configure` (hardware/sentinel.py: the same 4 bytes, from Indirect Data at 224, whose fourth byte shows a
reset servo the cycle after the reset; a cycle that folds a telemetry group in reads the direct block) ->
at most one due slow telemetry group (round-robin: status 10 Hz, motion 10 Hz, thermal 2 Hz while the
caller leaves the bus that much idle time; down to `FaultPolicy.telemetry_floor_share` of those rates when
cycles run back to back, the status group down to once per `FaultPolicy.sentinel_status_floor_s` then if
the sentinel is on) -> fault policy -> re-probe of one missing servo -> a frozen `ChainSnapshot`.
`cycle_start` / `cycle_finish` split it where the position replies are on the wire, so a caller can
compute meanwhile (the pipeline's next frame). A calm cycle (`calm_cycle`) does its per-servo snapshot
checks before collecting the replies, so little is left between the last reply and the next frame's bytes.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Literal

from servoface.hardware.bus import ServoBus
from servoface.hardware.calm_cycle import CalmCycle
from servoface.hardware.driver_reads import MOTION, POSITION, READ_FAILURES, STATUS, THERMAL, TelemetryGroup
from servoface.hardware.errors import (
    BusCorruptError,
    BusDisconnectedError,
    BusError,
    BusTimeoutError,
    DriverThreadError,
    GoalRejectedError,
    HardwareConfigError,
    ServoStatusError,
)
from servoface.hardware.fault_policy import FaultPolicy, ThermalTrend, eased_goal
from servoface.hardware.fault_reactions import FaultReactions
from servoface.hardware.goal_check import check_goals
from servoface.hardware.registers import Register
from servoface.hardware.sentinel import SENTINEL, SENTINEL_SHORT, SentinelMap
from servoface.hardware.servo_config import ConfigReport, ServoSpec, check_specs, configure_servo
from servoface.hardware.servo_record import ServoRecord
from servoface.hardware.snapshot import ChainSnapshot, FaultEvent, FaultKind, ServoState, StateCapture

CONFIGURE_QUIET_S = (0.2, 0.8)  # after a failed configure try, wait this long for quiet (a starved far end, a
# late reply): 3 tries span over a second, so a busy host or emulator does not fail an open; a servo really
# missing costs that second once, at start-up
TORQUE_OFF_QUIET_S = (0.03, 0.12, 0.3)  # after a failed torque-off, wait this long for quiet (per pass)
FastSyncRead = Literal[True, False, "auto"]  # `Driver`'s ``fast_sync_read``
OFF_BY_REQUEST = "off by request (position_sentinel=False): positions read directly (Present Position, 132)"


class Driver(CalmCycle):
    """Drives a configured chain. Not thread-safe by design: the thread that first uses it owns it.

    ``clock``: seconds, monotonic (tests may pass the emulator's clock). ``fast_sync_read``: read positions
    with Fast Sync Read (one combined status packet instead of one per servo; firmware support needed):
    ``"auto"`` (default) probes once, at the end of :meth:`configure` (or at the first cycle if the chain
    was not configured), and uses it if every servo answers (`fast_read_info` says which and why); ``True``
    / ``False`` force it. Either way a chain on which it later fails while single reads work falls back to
    plain Sync Read (with an event).

    ``position_sentinel`` (default on): at :meth:`configure`, map a witness byte and Present Position into Indirect
    Data at 224 (hardware/sentinel.py; four Indirect Address slots, 1..4 or 17..20, found by read-back) and read
    positions there, so each cycle's position read also shows a servo that was reset (its map gone: the witness byte
    reads 0): seen, its position discarded, re-configured and re-pinned the next cycle. The read is 3 bytes per
    servo (witness + 16-bit position) when every servo is in Position Control Mode with a Homing Offset that keeps
    it in 16 bits, a byte less than Present Position's own (4.5 to 6.5 % of a 24-servo cycle's wire time), else 4
    (witness + 24 bits). Because of the witness the status group is read back to back only once per
    `FaultPolicy.sentinel_status_floor_s` (2 s) instead of its floor share (0.4 s). Not dropped altogether: that a
    lost map reads 0 is verified on the emulator only, and the status read (torque found off) is the backstop on a
    servo where it is not so. ``False``: no Indirect Address is written and positions are read directly (132).
    `sentinel_info` says which path is in use and why (a chain where the map does not verify on every servo reads
    directly, with an event ``SENTINEL``).
    """

    def __init__(
        self,
        bus: ServoBus,
        specs: Sequence[ServoSpec],
        *,
        policy: FaultPolicy | None = None,
        clock: Callable[[], float] = time.monotonic,
        fast_sync_read: FastSyncRead = "auto",
        position_sentinel: bool = True,
    ) -> None:
        if not (fast_sync_read is True or fast_sync_read is False or fast_sync_read == "auto"):
            raise HardwareConfigError(f"fast_sync_read={fast_sync_read!r}: expected True, False or 'auto'")
        if position_sentinel is not True and position_sentinel is not False:
            raise HardwareConfigError(f"position_sentinel={position_sentinel!r}: expected True or False")
        self.position_sentinel = position_sentinel
        self.bus = bus
        self.policy = policy or FaultPolicy()
        self.fast_sync_read = fast_sync_read is True
        self._fast_probe_pending = fast_sync_read == "auto"
        self.fast_read_info = (
            "auto: not probed yet (at the end of configure, or the first cycle)"
            if self._fast_probe_pending
            else f"forced: fast_sync_read={fast_sync_read}"
        )
        self._clock = clock
        self._records: dict[int, ServoRecord] = {
            s.servo_id: ServoRecord(
                s,
                s.model_info,
                ThermalTrend(self.policy.thermal_window_s),
                s.temperature_limit_c or s.model_info.default_temperature_limit_c,
            )
            for s in check_specs(specs)
        }
        if not self._records:
            raise HardwareConfigError("Driver needs at least one ServoSpec")
        self.servo_ids: tuple[int, ...] = tuple(self._records)
        self._specs = {sid: rec.spec for sid, rec in self._records.items()}
        self._groups = [
            TelemetryGroup("status", STATUS, 1.0 / self.policy.status_hz),
            TelemetryGroup("motion", MOTION, 1.0 / self.policy.motion_hz),
            TelemetryGroup("thermal", THERMAL, 1.0 / self.policy.thermal_hz),
        ]
        self.telemetry_reads = {g.name: 0 for g in self._groups}
        self._owner: int | None = threading.get_ident()
        self._connected = True
        self._last_reopen_s = float("-inf")
        self._cycle = 0
        self._cycle_events: list[FaultEvent] = []
        self.events: deque[FaultEvent] = deque(maxlen=1000)
        self._reactions = FaultReactions(bus, self.policy, self._emit, self._recover, self._request_read)
        self._probe_index = 0
        self._group_failed = False
        self._fast_failures = 0
        self._last: ChainSnapshot | None = None
        self._last_tx_s: float | None = None  # driver clock of the last cycle (feeds the Bus Watchdog)
        self.watchdog_rearms = 0  # times a pause made the driver clear and re-arm the watchdog
        self.configure_retries = 0  # configure attempts repeated after a timeout / corrupt reply
        self._stop_reopened = False  # a stop re-opens a failed port at most once
        self._cycle_now: float | None = None  # set between cycle_start and cycle_finish
        self._position_ids: list[int] | None = None
        self.fold_telemetry = True  # a due motion / thermal group rides in the position read (driver_reads)
        self._folded: TelemetryGroup | None = None
        self._folded_this_cycle = False
        self._idle_s = float("inf")
        self._busy_s = 0.0  # how long the last cycle took (clock)
        self._patient = False
        self._last_end_s = float("-inf")  # clock at the end of the last cycle
        self._calm_events = 0
        self._sentinel = False
        self._sentinel_read = SENTINEL  # the read at 224 while `_sentinel`: 4 bytes, or 3 (`SENTINEL_SHORT`)
        self._witness: dict[int, int] = {}
        self._maps: dict[int, SentinelMap] = {}
        self._block = POSITION
        self._remap_failed: dict[int, float] = {}
        self.sentinel_info = (
            "not configured: positions read directly (Present Position, 132)" if position_sentinel else OFF_BY_REQUEST
        )

    # -- ownership ----------------------------------------------------------------------------------
    def _check_owner(self) -> None:
        me = threading.get_ident()
        if self._owner is None:
            self._owner = me
        elif self._owner != me:
            raise DriverThreadError(
                f"Driver on {getattr(self.bus, 'port_name', self.bus)!r} is owned by thread {self._owner}; "
                f"called from {me}. Use DriverThread.submit_goals() from other threads."
            )

    def hand_over(self) -> None:
        """Release ownership (call from the owner); the next thread to use the driver becomes its owner."""
        self._check_owner()
        self._owner = None

    def _request_read(self, group_name: str) -> None:
        for group in self._groups:
            if group.name == group_name:
                group.due_s = float("-inf")

    # -- events -------------------------------------------------------------------------------------
    def _emit(self, servo_id: int | None, kind: FaultKind, reaction: str) -> None:
        ev = FaultEvent(self._clock(), servo_id, kind, reaction)
        self._cycle_events.append(ev)
        self.events.append(ev)

    # -- set-up -------------------------------------------------------------------------------------
    def limits_tick(self, servo_id: int) -> tuple[int, int]:
        return self._records[servo_id].limits_tick

    def temperature_limit_c(self, servo_id: int) -> int:
        """The Temperature Limit the thermal policy works against (configured, else the model's default)."""
        return self._records[servo_id].temperature_limit_c

    def respec(self, specs: Sequence[ServoSpec]) -> None:
        """New specs for the same servos (ids and models), e.g. the position limits of a new calibration.
        Nothing is written: :meth:`configure` (torque off) writes them; until then goals are guarded by the
        new limits only. Owner thread only."""
        self._check_owner()
        new = {s.servo_id: s for s in check_specs(specs)}
        if set(new) != set(self._records):
            raise HardwareConfigError(
                f"respec: servo ids {sorted(new)} differ from the chain's {sorted(self._records)}"
            )
        for sid, spec in new.items():
            if spec.model_info != self._records[sid].info:
                raise HardwareConfigError(f"respec: servo {sid} is a {self._records[sid].info.name}, not {spec.model}")
        for sid, spec in new.items():
            self._records[sid].spec = spec
        self._specs = {sid: rec.spec for sid, rec in self._records.items()}

    def configure(self, *, allow_missing: bool = False) -> dict[int, ConfigReport]:
        """Write every spec (EEPROM with torque off, verified by read-back). Torque is left off.

        A servo's sequence (ping, reads, writes, read-back; every step idempotent) that fails on a timeout or
        a corrupt reply is tried again, up to `FaultPolicy.configure_attempts` times, after the line has been
        quiet for 0.2 / 0.8 s (a late reply must pass first, never be taken for the next answer); each
        retry is counted in ``configure_retries``. A servo that still does not answer raises `BusTimeoutError`
        / `BusCorruptError` — or, with ``allow_missing``, is marked missing (event ``MISSING``) and configured
        when it first answers a re-probe ping. A wrong model or a value that does not read back is never
        retried.
        """
        self._check_owner()
        reports = {}
        self._sentinel, self._maps = False, {}  # decided afresh below (`_decide_sentinel`)
        for rec in self._records.values():
            try:
                reports[rec.servo_id] = self._configure_retried(rec)
            except (BusTimeoutError, BusCorruptError):
                if not allow_missing:
                    raise
                self._mark_missing(rec, self._clock(), "did not answer during configure")
        self._decide_sentinel()
        if self._fast_probe_pending and self._connected:
            self._probe_fast_read(self._clock())
        return reports

    def _configure_retried(self, rec: ServoRecord) -> ConfigReport:
        for attempt in range(self.policy.configure_attempts - 1):
            try:
                return self._configure_one(rec)
            except (BusTimeoutError, BusCorruptError):
                self.configure_retries += 1
                quiet_s = CONFIGURE_QUIET_S[min(attempt, len(CONFIGURE_QUIET_S) - 1)]
                drain = getattr(self.bus, "drain", None)
                if drain is not None:
                    drain(quiet_s=quiet_s, max_s=max(0.3, 2 * quiet_s))
        return self._configure_one(rec)  # the last try: its error is the caller's

    def _configure_one(self, rec: ServoRecord) -> ConfigReport:
        report = configure_servo(self.bus, rec.spec, position_sentinel=self.position_sentinel)
        rec.torque_on = False
        rec.temperature_limit_c = report.limits[Register.TEMPERATURE_LIMIT]
        rec.current_limit = report.limits[Register.CURRENT_LIMIT] if rec.info.reports_current else None
        if rec.derated:  # configuration wrote the spec's profile; keep the derated one
            self.bus.write(rec.servo_id, Register.PROFILE_VELOCITY, self._reactions.derated_profile_velocity(rec))
        smap = report.sentinel
        if smap is not None:
            self._maps[rec.servo_id] = smap
            self._witness[rec.servo_id] = smap.witness
            if self._sentinel and smap.slot is None:  # a servo replaced, its firmware changed: 224 is not it
                self._sentinel_off(f"re-configure: {smap.why}")
            elif self._sentinel and not smap.short and self._sentinel_read is SENTINEL_SHORT:
                self._sentinel_on(f"re-configure: {smap.why}")  # its positions need 24 bits: 4-byte reads
        self._remap_failed.pop(rec.servo_id, None)
        return report

    def _decide_sentinel(self) -> None:
        """After `configure`: positions through the sentinel (hardware/sentinel.py) when every configured
        servo's map verified (each at 224: one Sync Read reads one address from all); else direct reads of
        Present Position for the chain, with an event that says why. Servos missing now are checked when
        they are configured (`_configure_one`)."""
        maps = self._maps
        refused = [m.why for m in maps.values() if m.slot is None]
        if not self.position_sentinel:
            self.sentinel_info = OFF_BY_REQUEST
        elif not maps:
            self.sentinel_info = "no servo configured: positions read directly (Present Position, 132)"
        elif refused:
            self._sentinel_off("; ".join(refused))
        else:
            long = [m.why for m in maps.values() if not m.short]
            self._sentinel_on("; ".join(long) if long else "")

    def _sentinel_on(self, why_long: str) -> None:
        """Positions through the sentinel: 3-byte reads unless ``why_long`` names a servo that needs 4."""
        self._sentinel = True
        self._sentinel_read = SENTINEL if why_long else SENTINEL_SHORT
        maps = self._maps
        slots = {f"{f}..{f + 3}": sorted(s for s, m in maps.items() if m.slot == f) for f in (1, 17)}
        size = (
            f"4 bytes: witness + position bits 0..23, as {why_long}"
            if why_long
            else ("3 bytes: witness + position bits 0..15, every servo in Position Control Mode")
        )
        self.sentinel_info = (
            f"positions read through Indirect Data at {SENTINEL.address} ({size}; Status Return Level "
            f"sentinel; Indirect Address slots {', '.join(f'{k} on servos {v}' for k, v in slots.items() if v)})"
        )

    def _sentinel_off(self, why: str) -> None:
        """The chain reads Present Position directly; resets are seen by the status group (floor rate)."""
        self._sentinel = False
        self.sentinel_info = f"positions read directly (Present Position, 132): {why}"
        self._emit(
            None,
            FaultKind.SENTINEL,
            f"{why}: positions read directly; a reset servo is seen by the status read at its floor rate",
        )

    def _pin_and_enable(self, rec: ServoRecord) -> None:
        """Bus Watchdog cleared, Goal Position := Present Position (clamped into the limits), Torque Enable = 1,
        then the watchdog armed (`FaultPolicy.watchdog_s`): if the host stops talking, the servo stops."""
        units = self.policy.watchdog_units
        if units:  # a tripped watchdog (an earlier controller died) refuses goals until it is cleared
            self.bus.write(rec.servo_id, Register.BUS_WATCHDOG, 0)
        present = self.bus.read(rec.servo_id, Register.PRESENT_POSITION)
        goal = rec.clamp(present)
        self._write_goal_single(rec, goal)
        self.bus.write(rec.servo_id, Register.TORQUE_ENABLE, 1)
        if units:
            self.bus.write(rec.servo_id, Register.BUS_WATCHDOG, units)
        rec.position_tick, rec.position_t_s = present, self._clock()
        rec.torque_on = True
        self._last_tx_s = self._clock()

    def torque_on(self, servo_ids: Iterable[int] | None = None) -> None:
        """Torque on, each servo's goal first pinned to where it is (no jump)."""
        self._check_owner()
        for rec in self._select(servo_ids):
            rec.torque_wanted = True
            if not rec.missing and not rec.latched and rec.reboot_at_s is None:
                try:
                    self._pin_and_enable(rec)
                except (BusTimeoutError, BusCorruptError):  # pinned and enabled when it answers again
                    self._mark_missing(rec, self._clock(), "did not answer torque-on")

    def torque_off(self, servo_ids: Iterable[int] | None = None, *, attempts: int | None = None) -> tuple[int, ...]:
        """Torque Enable = 0 on every servo (missing ones too: they may answer), each tried up to ``attempts``
        times (default `FaultPolicy.torque_off_attempts`), carrying on past any servo that fails.

        Returns the ids that could not be reached — their torque may still be on; an empty tuple means
        every servo confirmed torque off. Never raises for a bus failure (a dead port: every servo not yet
        reached is returned after one re-open attempt).
        """
        self._check_owner()
        tries = max(1, attempts if attempts is not None else self.policy.torque_off_attempts)
        records = self._select(servo_ids)
        for rec in records:
            rec.torque_wanted = False
        if self._connected or self._reopen_once():
            try:  # one broadcast first: every servo that hears it stops at once, whatever its replies do
                self.bus.sync_write(Register.TORQUE_ENABLE, {rec.servo_id: 0 for rec in records})
            except BusError:
                pass
        pending = list(records)
        for attempt in range(tries):  # then confirm servo by servo; failures are retried in the next pass
            failed = []
            quiet_s = TORQUE_OFF_QUIET_S[min(attempt, len(TORQUE_OFF_QUIET_S) - 1)]  # longer each pass
            for rec in pending:
                if self._write_confirmed(rec.servo_id, Register.TORQUE_ENABLE, 0):
                    rec.torque_on = False
                else:
                    failed.append(rec)
                    self._drain(quiet_s)
            if len(failed) == len(pending) == len(records) and attempt >= 1:
                pending = failed  # nothing answers at all (the chain is gone): do not wait out every pass
                break
            pending = failed
            if not pending or not self._connected:
                break
        for rec in pending:
            self._emit(rec.servo_id, FaultKind.UNREACHED, f"torque off not confirmed after {tries} attempt(s)")
        return tuple(rec.servo_id for rec in pending)

    def _drain(self, quiet_s: float) -> None:
        """Let a late reply pass before the next servo is asked (it would collide with, or be taken for, its reply)."""
        drain = getattr(self.bus, "drain", None)
        if drain is not None and self._connected:
            drain(quiet_s=quiet_s, max_s=max(0.3, 2 * quiet_s))

    def _write_confirmed(self, servo_id: int, register: Register, value: int) -> bool:
        """One write; True once the servo acknowledged it (or reads ``value`` back after an error reply)."""
        try:
            self.bus.write(servo_id, register, value)
            return True
        except BusDisconnectedError:
            self._reopen_once()
            return False
        except ServoStatusError:  # answered with an error: believe only a read-back
            try:
                return bool(self.bus.read(servo_id, register) == value)
            except BusError:
                return False
        except BusError:  # timeout, corrupt reply, port busy: the next pass tries again
            return False

    def _reopen_once(self) -> bool:
        """One attempt to re-open a failed port while stopping (False: the port stays dead)."""
        if self._stop_reopened:
            return self._connected
        self._stop_reopened = True
        try:
            self.bus.reopen()
        except BusError:
            self._connected = False
            return False
        self._connected = True
        return True

    def disarm_watchdog(self, servo_ids: Iterable[int] | None = None) -> None:
        """Bus Watchdog := 0 (one attempt per servo, failures ignored): a clean close leaves no timer."""
        self._check_owner()
        if not self.policy.watchdog_units or not self._connected:
            return
        for rec in self._select(servo_ids):
            try:
                self.bus.write(rec.servo_id, Register.BUS_WATCHDOG, 0)
            except BusError:
                continue

    def _feed_watchdog(self, now: float) -> None:
        """After a pause longer than half the watchdog time (a slow frame, a caller that waited between
        motions), the watchdog may have tripped and would refuse every goal: clear and re-arm it first."""
        last_tx_s = self._last_tx_s  # the time test first: once per cycle, mostly all there is to do
        if last_tx_s is None or now - last_tx_s <= 0.5 * self.policy.watchdog_s:
            return
        units = self.policy.watchdog_units
        if not units:
            return
        ids = [rec.servo_id for rec in self._records.values() if rec.in_service]
        if ids:
            self.bus.sync_write(Register.BUS_WATCHDOG, {sid: 0 for sid in ids})
            self.bus.sync_write(Register.BUS_WATCHDOG, {sid: units for sid in ids})
            self.watchdog_rearms += 1

    def clear_fault(self, servo_id: int) -> None:
        """Acknowledge a latched fault: reboot the servo and bring it back (re-configured, goal re-pinned)."""
        self._check_owner()
        rec = self._records[servo_id]
        rec.latched = False
        rec.faults.discard(FaultKind.LATCHED)
        rec.faults.discard(FaultKind.HARDWARE_ERROR)
        rec.reboots.clear()
        rec.reboot_at_s, rec.reboot_reason = self._clock(), FaultKind.HARDWARE_ERROR

    def _select(self, servo_ids: Iterable[int] | None) -> list[ServoRecord]:
        if servo_ids is None:
            return list(self._records.values())
        ids = list(servo_ids)
        unknown = [i for i in ids if i not in self._records]
        if unknown:
            raise HardwareConfigError(f"unknown servo id(s) {unknown}; configured: {list(self._records)}")
        return [self._records[i] for i in ids]

    # -- goals --------------------------------------------------------------------------------------
    def validate_goals(self, goals_tick: Mapping[int, int]) -> dict[int, int]:
        """Every goal an integer tick inside its servo's configured limits, or `GoalRejectedError`."""
        return check_goals(goals_tick, self._specs)

    def _guard(self, rec: ServoRecord, tick: int) -> int:
        lo, hi = rec.limits_tick
        if not lo <= tick <= hi:  # the last line of defence before the wire; unreachable by design
            raise GoalRejectedError(rec.servo_id, tick, f"{rec.spec.label}: refusing to send {tick} outside {lo}..{hi}")
        return tick

    def _write_goal_single(self, rec: ServoRecord, tick: int) -> None:
        self.bus.write(rec.servo_id, Register.GOAL_POSITION, self._guard(rec, tick))
        rec.goal_tick = tick

    def _goal_frame(self, goals_tick: Mapping[int, int]) -> dict[int, int] | None:
        """`validate_goals` and `_write_goals`' frame in one pass over the goals, for the usual frame (a dict
        of plain int ids and ticks, every goal inside its servo's limits): the frame `_write_goals` would
        send for what `validate_goals` returns. None for any other frame (nothing judged here: the two
        checks then run as before, so a refusal and its message are theirs). Call it only when nothing can
        change a record before the write (connected, no Fast Sync Read probe pending)."""
        if type(goals_tick) is not dict:
            return None
        frame: dict[int, int] = {}
        records = self._records
        backoff = FaultKind.LOAD_BACKOFF
        for sid, goal in goals_tick.items():
            rec = records.get(sid) if type(sid) is int else None
            if rec is None or type(goal) is not int:
                return None
            spec = rec.spec
            if not spec.min_position_tick <= goal <= spec.max_position_tick:
                return None  # `validate_goals` refuses the whole frame, naming the servo
            if (
                rec.missing
                or not rec.torque_on
                or rec.latched
                or rec.reboot_at_s is not None
                or rec.recover_at_s is not None
            ):
                continue  # not `rec.in_service` (the same test, inlined: once per servo per frame)
            if rec.faults and backoff in rec.faults and rec.position_tick is not None:
                goal = eased_goal(goal, rec.position_tick, rec.backoff_scale, *rec.limits_tick)
                if not spec.min_position_tick <= goal <= spec.max_position_tick:
                    self._guard(rec, goal)  # the last line of defence before the wire; unreachable by design
            frame[sid] = goal  # an unchanged goal was checked against these limits just above
        return frame

    def _write_goals(self, goals: Mapping[int, int]) -> None:
        """The frame of validated ``goals`` (servos in service only, load back-off applied), guarded, sent."""
        frame: dict[int, int] = {}
        records = self._records
        backoff = FaultKind.LOAD_BACKOFF
        for sid, goal in goals.items():
            rec = records[sid]
            if (
                rec.missing
                or not rec.torque_on
                or rec.latched
                or rec.reboot_at_s is not None
                or rec.recover_at_s is not None
            ):
                continue  # not `rec.in_service` (the same test, inlined: once per servo per frame)
            if rec.faults and backoff in rec.faults and rec.position_tick is not None:
                goal = eased_goal(goal, rec.position_tick, rec.backoff_scale, *rec.limits_tick)
            spec = rec.spec  # the last line of defence before the wire (`_guard`), inlined: once per servo
            if not spec.min_position_tick <= goal <= spec.max_position_tick:
                self._guard(rec, goal)
            frame[sid] = goal
        self._send_goals(frame)

    def _send_goals(self, frame: dict[int, int]) -> None:
        """One Sync Write of a built frame (`_write_goals`, `_goal_frame`); the goals noted as written."""
        if frame:
            self.bus.sync_write(Register.GOAL_POSITION, frame)
            records = self._records
            for sid, tick in frame.items():
                records[sid].goal_tick = tick

    # -- reads with fallback ------------------------------------------------------------------------
    # -- missing servos, reconnects -----------------------------------------------------------------
    def _recover(self, rec: ServoRecord, kind: FaultKind) -> bool:
        """Re-configure a servo that is back (reconnected / rebooted / cooled) and re-pin its goal.

        If its Hardware Error Status is still set (the cause persists), the fault reaction starts over —
        each reboot counts toward `FaultPolicy.max_reboots`, after which the servo latches off.
        """
        now = self._clock()
        for k in (
            FaultKind.OVERLOAD,
            FaultKind.OVERHEATING,
            FaultKind.VOLTAGE_HIGH,
            FaultKind.VOLTAGE_LOW,
            FaultKind.INPUT_VOLTAGE,
        ):
            if k != FaultKind.VOLTAGE_LOW or rec.voltage_count == 0:
                rec.faults.discard(k)
        rec.derated = FaultKind.THERMAL_DERATE in rec.faults or FaultKind.VOLTAGE_LOW in rec.faults
        try:
            self._configure_one(rec)
            hw = self.bus.read(rec.servo_id, Register.HARDWARE_ERROR_STATUS)
            rec.missing, rec.failures, rec.stale = False, 0, False
            rec.hardware_error = type(rec.hardware_error).NONE
            if hw:
                self._reactions.on_status(rec, 0, hw, now)
                return True
            if rec.torque_wanted:
                self._pin_and_enable(rec)
        except (BusError, HardwareConfigError) as err:
            if isinstance(err, BusDisconnectedError):
                raise
            return False
        state = "torque on, goal re-pinned to present" if rec.torque_wanted else "torque left off"
        self._emit(rec.servo_id, kind, f"re-configured (verified), {state}")
        return True

    def _probe_missing(self, now: float) -> None:
        missing = [r for r in self._records.values() if r.missing]
        if not missing:
            return
        self._probe_index = (self._probe_index + 1) % len(missing)
        rec = missing[self._probe_index]
        if now - rec.last_probe_s < self.policy.reprobe_interval_s:
            return
        rec.last_probe_s = now
        try:
            self.bus.ping(rec.servo_id)
        except READ_FAILURES:
            return
        rec.recover_at_s = None
        self._recover(rec, FaultKind.RECONNECTED)

    def _on_disconnect(self, err: BusDisconnectedError) -> None:
        if self._connected:
            self._connected = False
            for rec in self._records.values():
                rec.missing, rec.stale, rec.torque_on = True, True, False
            self._emit(
                None,
                FaultKind.DISCONNECTED,
                f"{err}; all servos missing, port re-opened every {self.policy.reconnect_interval_s:g} s",
            )

    def _try_reopen(self, now: float) -> None:
        if now - self._last_reopen_s < self.policy.reconnect_interval_s:
            return
        self._last_reopen_s = now
        try:
            self.bus.reopen()
        except BusError:
            return
        self._connected = True
        for rec in self._records.values():
            rec.last_probe_s = float("-inf")
            try:
                self.bus.ping(rec.servo_id)
            except READ_FAILURES:
                continue
            self._recover(rec, FaultKind.RECONNECTED)

    # -- the cycle ----------------------------------------------------------------------------------
    def cycle(self, goals_tick: Mapping[int, int]) -> ChainSnapshot:
        """One control frame: one Sync Write of goals, position read, due telemetry, fault policy."""
        self.cycle_start(goals_tick)
        return self.cycle_finish()

    def cycle_start(self, goals_tick: Mapping[int, int]) -> None:
        """The first half of `cycle`: validate and write the goals, send the position read's instruction,
        and return while its replies are on the wire (the caller may compute, not use the bus, until
        `cycle_finish`). Bad goals raise here, before anything is sent."""
        self._check_owner()
        if self._cycle_now is not None:
            raise DriverThreadError("Driver.cycle_start called twice without cycle_finish in between")
        frame = self._goal_frame(goals_tick) if self._connected and not self._fast_probe_pending else None
        goals = self.validate_goals(goals_tick) if frame is None else frame  # raises: nothing sent
        self._cycle_events = []
        if self._fast_probe_pending and self._connected:  # "auto" on a chain this driver did not configure:
            try:  # probed before the cycle's clock reading, so a slow (failed) probe counts as a pause for
                self._probe_fast_read(self._clock())  # the Bus Watchdog (`_feed_watchdog` re-arms it)
            except BusDisconnectedError as err:
                self._on_disconnect(err)
        now = self._clock()
        self._idle_s = now - self._last_end_s
        self._patient = self._idle_s > self._busy_s  # a paced caller: spend least CPU, not least latency
        self._cycle_now = now
        self._position_ids = None
        try:
            if not self._connected:
                self._try_reopen(now)
            if self._connected:
                self._feed_watchdog(now)
                if frame is None:
                    self._write_goals(goals)
                else:
                    self._send_goals(frame)  # built before the cycle started: nothing since changes a record
                self._start_positions(now)
        except BusDisconnectedError as err:
            self._on_disconnect(err)
        except BaseException:
            self._cycle_now = None  # the cycle did not start: the next one may
            raise

    def cycle_finish(self) -> ChainSnapshot:
        """The second half of `cycle`: collect positions, due telemetry, fault policy; the snapshot."""
        self._check_owner()
        now, self._cycle_now = self._cycle_now, None
        if now is None:
            raise DriverThreadError("Driver.cycle_finish called without cycle_start")
        items: dict[int, ServoState | StateCapture] | None = None
        try:
            if self._connected:
                plan = self._plan_calm(now)  # while the position replies are (most likely) still on the wire
                if plan is None:
                    self._read_positions(now)
                else:
                    items = self._read_positions_calm(plan, now)  # None: not calm after all (positions applied)
                if items is None:
                    self._read_slow_group(now)
                    for rec in self._records.values():
                        if rec.reboot_at_s is not None or rec.recover_at_s is not None:  # else nothing to do
                            self._reactions.service(rec, now)
                    self._probe_missing(now)
        except BusDisconnectedError as err:
            self._on_disconnect(err)
        self._last_tx_s = now
        self._cycle += 1
        snapshot = self._freeze(now) if items is None else self._snapshot(now, items)
        self._last_end_s = self._clock()
        self._busy_s = self._last_end_s - now
        return snapshot

    def read_state(self) -> ChainSnapshot:
        """A cycle without goals (positions, due telemetry, policy)."""
        return self.cycle({})

    def snapshot(self) -> ChainSnapshot | None:
        """The snapshot of the last cycle (None before the first)."""
        return self._last

    def _freeze(self, now: float) -> ChainSnapshot:
        """The cycle's snapshot of every record's `ServoRecord.freeze_lazy` (states built when looked at)."""
        return self._snapshot(now, {sid: rec.freeze_lazy() for sid, rec in self._records.items()})

    def _snapshot(self, now: float, items: dict[int, ServoState | StateCapture]) -> ChainSnapshot:
        """The cycle's snapshot of ``items`` (`_freeze`'s, or a calm cycle's captures: `CalmCycle`)."""
        snap = ChainSnapshot.owning(  # the fresh dict is the snapshot's own: no defensive copy
            now,
            self._cycle,
            items,
            tuple(self._cycle_events),
            self.bus.stats.copy(),
            self._connected,
        )
        self._last = snap
        return snap

    def close(self, *, torque_off: bool = False) -> tuple[int, ...]:
        """Optionally torque everything off (retried per servo) and disarm the Bus Watchdog, then close the bus.

        Returns the ids whose torque-off was not confirmed (empty without ``torque_off``).
        """
        self._check_owner()
        unreached: tuple[int, ...] = ()
        try:
            if torque_off:
                unreached = self.torque_off()
                reached = [sid for sid in self.servo_ids if sid not in unreached]
                if reached:
                    self.disarm_watchdog(reached)
        finally:
            self.bus.close()
        return unreached

    @property
    def position_read_bytes(self) -> int:
        """Bytes per servo of a plain cycle's position read: 3 or 4 through the sentinel, 4 read directly
        (a cycle that folds a telemetry group in reads more; wire-time arithmetic: `hardware.wire`)."""
        return self._sentinel_read.size if self._sentinel else POSITION[0].size

    def servo_problems(self) -> dict[str, tuple[int, ...]]:
        """Servos that ended the run out of service: ``latched`` (needs `clear_fault`), ``missing``."""
        return {
            "latched": tuple(sid for sid, r in self._records.items() if r.latched),
            "missing": tuple(sid for sid, r in self._records.items() if r.missing),
        }
