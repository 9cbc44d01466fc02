"""The reading half of `Driver`: group reads with per-servo fallback, missing-servo marking, and the
round-robin slow telemetry (a mixin: it shares the driver's records, bus, policy and event sink)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from servoface.hardware.bus import ServoBus
from servoface.hardware.errors import (
    BusCorruptError,
    BusDisconnectedError,
    BusError,
    BusTimeoutError,
    HardwareConfigError,
    ServoStatusError,
)
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.fault_reactions import FaultReactions
from servoface.hardware.registers import Register, span
from servoface.hardware.sentinel import TICK_SIGN
from servoface.hardware.servo_record import ServoRecord
from servoface.hardware.snapshot import FaultKind

POSITION = (Register.PRESENT_POSITION,)
MOTION = (Register.MOVING, Register.PRESENT_CURRENT, Register.PRESENT_VELOCITY)  # 122..131, one block
THERMAL = (Register.PRESENT_INPUT_VOLTAGE, Register.PRESENT_TEMPERATURE)  # 144..146
STATUS = (Register.TORQUE_ENABLE, Register.HARDWARE_ERROR_STATUS)  # 64..70
READ_FAILURES = (BusTimeoutError, BusCorruptError, ServoStatusError)
FOLDABLE = ("motion", "thermal")  # groups whose block adjoins Present Position: read with it (see _position_block)
FAST_READ_GIVE_UP = 3  # cycles of "fast read fails, single reads work" before falling back to Sync Read
PROBE_QUIET_S = 0.05  # after a failed Fast Sync Read probe, let the line be this quiet (a partial reply's tail)


@dataclass
class TelemetryGroup:
    """A slow group: read every ``period_s`` when the bus has the idle time for it (see `ChainReads`)."""

    name: str
    registers: tuple[Register, ...]
    period_s: float
    due_s: float = float("-inf")
    cost_s: float = 0.0  # wall time its last read took (0 until measured: the first read always fits)


class ChainReads:
    """Reads for `Driver` (see its docstring for the cycle). Attributes are set by `Driver.__init__`."""

    bus: ServoBus
    policy: FaultPolicy
    fast_sync_read: bool  # positions are read with Fast Sync Read (resolved: see `_probe_fast_read`)
    fast_read_info: str  # which read the positions use, and why (the probe's or the fallback's news)
    _fast_probe_pending: bool  # ``fast_sync_read="auto"`` not yet decided by a probe
    _records: dict[int, ServoRecord]
    _groups: list[TelemetryGroup]
    _reactions: FaultReactions
    _group_failed: bool
    _fast_failures: int
    _clock: Callable[[], float]
    telemetry_reads: dict[str, int]  # slow group reads so far, by group name
    _idle_s: float  # how long the caller left the bus idle before this cycle (inf on the first)
    _patient: bool  # that idle time exceeds the last cycle's own: replies are slept for, not polled
    _position_ids: list[int] | None  # ids whose position read `cycle_start` sent (None: nothing sent)
    fold_telemetry: bool  # read a due motion / thermal group in the position read's transaction
    _folded: TelemetryGroup | None  # the group the position read in flight carries
    _folded_this_cycle: bool  # a group rode in this cycle's position read
    _sentinel: bool  # positions read through the sentinel's map at 224 (hardware/sentinel.py)
    _sentinel_read: Register  # that read: `SENTINEL` (4 bytes) or `SENTINEL_SHORT` (3)
    _witness: dict[int, int]  # per servo, the sentinel byte while its map holds
    _block: tuple[Register, ...]  # the registers of the position read in flight (`_position_block`)
    _remap_failed: dict[int, float]  # servo -> when its failing re-configure after a lost sentinel was tried

    def _emit(self, servo_id: int | None, kind: FaultKind, reaction: str) -> None:
        raise NotImplementedError

    def _configure_one(self, rec: ServoRecord) -> object:
        raise NotImplementedError

    def _read_group(
        self, ids: list[int], registers: tuple[Register, ...], fast: bool = False, started: bool = False
    ) -> dict[int, dict[Register, int]]:
        """Group read with retries; on failure, read servo by servo to find the silent one. ``started``:
        the first attempt's instruction is already on the wire (`sync_read_start`); collect its replies."""
        self._group_failed = False
        if not ids:
            return {}
        for attempt in range(1 + self.policy.retries):
            try:
                if not (started and attempt == 0):
                    self.bus.sync_read_start(ids, registers, fast=fast)
                return self.bus.sync_read_finish(patient=self._patient)
            except (BusTimeoutError, BusCorruptError):
                continue
        self._group_failed = True
        out: dict[int, dict[Register, int]] = {}
        for sid in ids:
            for _ in range(1 + self.policy.retries):
                try:
                    out[sid] = self.bus.read_many(sid, registers)
                    break
                except READ_FAILURES:
                    continue
        return out

    def _mark_results(self, ids: list[int], got: Mapping[int, object], now: float) -> None:
        for sid in ids:
            rec = self._records[sid]
            if sid in got:
                rec.failures = 0
                rec.stale = False
                continue
            rec.failures += 1
            rec.stale = True
            if rec.failures >= self.policy.missing_after_failures and not rec.missing:
                self._mark_missing(rec, now, f"no reply in {rec.failures} cycles")

    def _mark_missing(self, rec: ServoRecord, now: float, why: str) -> None:
        rec.missing, rec.stale, rec.torque_on = True, True, False
        rec.last_probe_s = now
        self._emit(
            rec.servo_id,
            FaultKind.MISSING,
            f"{why}: excluded from group reads and goal frames, re-probed every "
            f"{self.policy.reprobe_interval_s:g} s; other servos continue",
        )

    def _readable(self, now: float) -> list[int]:
        """Ids worth asking: not missing, and not inside the silence after a reboot."""
        return [
            sid
            for sid, rec in self._records.items()
            if not rec.missing and (rec.recover_at_s is None or rec.recover_at_s <= now or rec.reboot_at_s is not None)
        ]

    def _position_block(self, now: float) -> tuple[Register, ...]:
        """The registers of this cycle's position read: Present Position, and — when the motion or the
        thermal group is due (`_due_group`) and `fold_telemetry` is on — that group's registers too, read
        in the same transaction (their blocks adjoin Present Position: 122..135 / 132..146, one reply per
        servo instead of a second group read with its own instruction, turnaround and parse). With the
        position sentinel on (`_sentinel`), a cycle that folds nothing reads the sentinel (3 or 4 bytes at
        224: `_sentinel_read`) instead; one that folds reads the direct block as above (no witness that cycle:
        the next plain cycle checks it)."""
        self._folded = None
        block: tuple[Register, ...] = (self._sentinel_read,) if self._sentinel else POSITION
        if self.fold_telemetry:
            group = self._due_group(now)
            if group is not None and group.name in FOLDABLE:
                self._folded = group
                block = POSITION + group.registers
        self._block = block
        return block

    def _start_positions(self, now: float) -> None:
        """Send the position read's instruction; `_read_positions` collects the replies."""
        ids = self._readable(now)
        self._position_ids = None
        registers = self._position_block(now)
        if ids:
            try:
                self.bus.sync_read_start(ids, registers, fast=self.fast_sync_read)
            except (BusTimeoutError, BusCorruptError):
                return  # nothing on the wire: `_read_positions` reads afresh
            self._position_ids = ids

    def _read_positions(self, now: float) -> None:
        self._apply_positions(now, *self._collect_positions(now))

    def _collect_positions(self, now: float) -> tuple[list[int], tuple[Register, ...], dict[int, dict[Register, int]]]:
        """The position read's replies (of the instruction `_start_positions` sent, else of one sent now):
        (ids asked, registers read, values of those that answered)."""
        started, self._position_ids = self._position_ids, None
        if started is None:
            ids = self._readable(now)
            registers = self._position_block(now)
        else:
            ids = started
            registers = self._block
        got = self._read_group(ids, registers, fast=self.fast_sync_read, started=started is not None)
        if self.fast_sync_read and ids:
            self._check_fast_read_support(self._group_failed and len(got) == len(ids))
        return ids, registers, got

    def _apply_positions(
        self, now: float, ids: list[int], registers: tuple[Register, ...], got: dict[int, dict[Register, int]]
    ) -> None:
        """The position read's values into the records; a folded group's too; the silent ones marked.
        A read of the sentinel (``registers[0]``, whatever `_sentinel` says now): a reply whose first byte is
        not the servo's witness is a reset servo's (`_sentinel_lost`): its position is discarded, never
        applied."""
        records = self._records
        position = registers[0]
        sign = TICK_SIGN.get(position)  # a read of the sentinel: its position's sign bit; None: a direct read
        witness = self._witness
        lost: dict[int, int] = {}
        for sid, values in got.items():  # `_mark_results` for the servos that answered, in the same pass
            tick = values[position]
            if sign is not None:  # the witness byte, then the position (`sentinel.split`, inline)
                if tick & 0xFF != witness.get(sid, -1):
                    lost[sid] = tick & 0xFF
                    continue
                tick = ((tick >> 8) ^ sign) - sign
            rec = records[sid]
            rec.position_tick = tick
            rec.position_t_s = now
            rec.failures = 0
            rec.stale = False
        group, self._folded = self._folded, None
        if group is not None and ids:
            self._folded_this_cycle = True
            group.due_s = now + group.period_s
            # what riding along costs: the extra bytes' wire time (the idle-time rule of `_due_group`)
            extra_bytes = len(ids) * (span(registers)[1] - span(POSITION)[1])
            group.cost_s = extra_bytes * 10.0 / max(1, int(getattr(self.bus, "baud", 1_000_000)))
            self.telemetry_reads[group.name] += 1
            self._apply_group(group, got, now)  # a folded read is the direct block: no witness in it
        for sid, byte in lost.items():
            self._sentinel_lost(records[sid], byte, now)
        if len(got) < len(ids):  # the silent ones (`got` holds only ids asked for)
            self._mark_results([sid for sid in ids if sid not in got], got, now)

    def _sentinel_lost(self, rec: ServoRecord, byte: int, now: float) -> None:
        """A position reply whose sentinel byte is not the servo's witness: its Indirect Address map is gone,
        so the servo was reset (RAM back to defaults, torque off). The position is discarded (stale). In
        service: the reset reaction of the status read (`FaultReactions.on_reset_seen`: re-configured, which
        rewrites the map, and goal re-pinned, this cycle). Out of service (torque off by choice or by a
        fault reaction, a reboot pending, latched): re-configured now with torque left off (torque is never
        turned on from here), so the map and the RAM settings are back and its own fault reaction carries on;
        a re-configure that fails is tried again at most every `FaultPolicy.reprobe_interval_s`, with one
        event. Being recovered already (after a reboot of ours): nothing, its recovery re-maps it."""
        rec.stale = True
        rec.failures = 0
        if rec.recover_at_s is not None or rec.missing:
            return
        sid = rec.servo_id
        why = f"position sentinel read {byte}, expected {self._witness.get(sid)}: Indirect Address map lost"
        if rec.in_service:
            self._reactions.on_reset_seen(rec, why, now)
            return
        failed_s = self._remap_failed.get(sid)
        if failed_s is not None and now - failed_s < self.policy.reprobe_interval_s:
            return
        try:
            self._configure_one(rec)
        except BusDisconnectedError:
            raise
        except (BusError, HardwareConfigError) as err:
            self._remap_failed[sid] = now
            if failed_s is None:
                self._emit(
                    sid,
                    FaultKind.RECONNECTED,
                    f"servo reset ({why}); re-configure failed ({err}): torque stays off, re-configure tried "
                    f"again every {self.policy.reprobe_interval_s:g} s",
                )
            return
        self._remap_failed.pop(sid, None)
        self._emit(sid, FaultKind.RECONNECTED, f"servo reset while out of service ({why}): re-configured, torque off")

    def _probe_fast_read(self, now: float) -> None:
        """``fast_sync_read="auto"``: one Fast Sync Read of Present Position from every readable servo. A
        valid combined reply with every id: positions are read fast from now on; anything else (no reply,
        a corrupt or short one, a servo missing from it: firmware without the instruction) leaves plain
        Sync Read, with an event that says why. A read, so safe; never raises for a chain without support
        (a failed port is the caller's, as in any read). With no servo to ask, it waits for the next call."""
        ids = self._readable(now)
        if not ids:
            return
        self._fast_probe_pending = False
        try:
            got = self.bus.sync_read(ids, POSITION, fast=True)
        except BusDisconnectedError:
            self._fast_probe_pending = True
            raise
        except BusError as err:
            self._fast_probe_failed(ids, err)
            return
        if set(got) != set(ids):  # the bus checks this already; a reply without every id is no support
            self._fast_probe_failed(ids, BusCorruptError(f"fast sync read probe: ids {sorted(got)} answered", ids))
            return
        self.fast_sync_read = True
        self.fast_read_info = f"auto: servos {ids} answered a Fast Sync Read probe: positions read with Fast Sync Read"

    def _fast_probe_failed(self, ids: list[int], err: BusError) -> None:
        self.fast_sync_read = False
        self.fast_read_info = (
            f"auto: the Fast Sync Read probe of servos {ids} failed ({err}): positions read with plain Sync Read"
        )
        self._emit(
            None,
            FaultKind.TIMEOUT if isinstance(err, BusTimeoutError) else FaultKind.CORRUPT,
            f"Fast Sync Read probe failed ({err}; firmware without it?): positions read with plain Sync Read",
        )
        drain = getattr(self.bus, "drain", None)  # a partial combined reply's tail must not meet the next read
        if drain is not None:
            drain(quiet_s=PROBE_QUIET_S, max_s=max(0.3, 2 * PROBE_QUIET_S))

    def _check_fast_read_support(self, only_fast_failed: bool) -> None:
        """Fast Sync Read failing while every single read works means the firmware lacks it: fall back."""
        self._fast_failures = self._fast_failures + 1 if only_fast_failed else 0
        if self._fast_failures >= FAST_READ_GIVE_UP:
            self.fast_sync_read = False
            self.fast_read_info = (
                f"Fast Sync Read failed {self._fast_failures} cycles running while single reads worked: "
                "positions read with plain Sync Read"
            )
            self._emit(
                None,
                FaultKind.CORRUPT,
                f"Fast Sync Read failed {self._fast_failures} cycles running while every servo answered "
                "single reads (firmware without it?): positions now read with plain Sync Read",
            )

    def _due_group(self, now: float) -> TelemetryGroup | None:
        """The most overdue group, if it is to be read this cycle: at once when asked for (an alert, a
        reaction, the first read), when the caller left the bus idle for at least as long as its last read
        took (nominal rate: the read fills idle time), or once overdue beyond the floor rate — for the status
        group while the position sentinel is on, once `FaultPolicy.sentinel_status_floor_s` has passed since
        its last read (every plain position reply shows a reset; this read is the backstop)."""
        policy = self.policy
        late = 1.0 / policy.telemetry_floor_share - 1.0
        best: TelemetryGroup | None = None
        relaxed = self._groups[0] if self._sentinel else None  # the status group, with the sentinel on
        for g in self._groups:  # the first most overdue of the ready ones (as min() picks)
            due = g.due_s
            if due > now or (best is not None and due >= best.due_s):
                continue
            lag = g.period_s * late if g is not relaxed else policy.sentinel_status_floor_s - g.period_s
            if due == float("-inf") or self._idle_s >= g.cost_s or now >= due + lag:
                best = g
        return best

    def _read_slow_group(self, now: float) -> None:
        """At most one slow group per cycle: none after a folded one (`_position_block`), except the status
        group an Alert bit asks for (the why of an alarm is read the cycle it is seen)."""
        folded = self._folded_this_cycle
        self._folded_this_cycle = False
        alarm = False
        if self.bus.alerts:  # an Alert bit (any reply, the position read's included): read the why now,
            # unless every alerting servo's error is already known (the bit stays set until its reboot)
            if any(sid not in self._records or not self._records[sid].hardware_error for sid in self.bus.alerts):
                self._groups[0].due_s = float("-inf")
                alarm = True
            self.bus.alerts.clear()
        if folded and not alarm:
            return
        group = self._due_group(now)
        if group is None:
            return
        group.due_s = now + group.period_s
        self.telemetry_reads[group.name] += 1
        ids = self._readable(now)
        t0 = self._clock()
        got = self._read_group(ids, group.registers, fast=self.fast_sync_read)  # one combined reply if it works
        group.cost_s = self._clock() - t0
        self._apply_group(group, got, now)
        if group.name == "status":  # its replies' Alert bits are what it just read the detail of
            self.bus.alerts.difference_update(got)
        self._mark_results(ids, got, now)

    def _apply_group(self, group: TelemetryGroup, got: Mapping[int, Mapping[Register, int]], now: float) -> None:
        """A slow group's fresh values into the records and the fault reactions (the group's branch chosen
        once, not per servo)."""
        records, reactions = self._records, self._reactions
        if group.name == "status":
            on_status, torque, error = reactions.on_status, Register.TORQUE_ENABLE, Register.HARDWARE_ERROR_STATUS
            for sid, values in got.items():
                on_status(records[sid], values[torque], values[error], now)
        elif group.name == "motion":
            for sid, values in got.items():
                rec = records[sid]
                rec.apply_motion(values, now)
                reactions.on_motion(rec)
        else:
            on_thermal, voltage, temperature = (
                reactions.on_thermal,
                Register.PRESENT_INPUT_VOLTAGE,
                Register.PRESENT_TEMPERATURE,
            )
            for sid, values in got.items():
                on_thermal(records[sid], values[voltage], values[temperature], now)
