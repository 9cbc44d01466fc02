"""The fault policy's reactions: what the driver writes when telemetry shows a fault (bus thread only).

Each reaction appends a `FaultEvent`; the README section "Faults" tabulates them.
"""

from __future__ import annotations

from collections.abc import Callable

from servoface.hardware.bus import ServoBus
from servoface.hardware.errors import BusCorruptError, BusTimeoutError, ServoStatusError
from servoface.hardware.fault_policy import FaultPolicy, thermal_level, voltage_state
from servoface.hardware.registers import DRIVE_MODE_TIME_BASED_PROFILE, HardwareErrorBits, Register
from servoface.hardware.servo_record import ServoRecord
from servoface.hardware.snapshot import FaultEvent, FaultKind

Emit = Callable[[int | None, FaultKind, str], None]
_LATCHING = HardwareErrorBits.MOTOR_ENCODER | HardwareErrorBits.ELECTRICAL_SHOCK
_NO_BITS = HardwareErrorBits(0)
TIME_BASED_DERATE_MS = 1000


class FaultReactions:
    """Applies `FaultPolicy` to one servo's fresh telemetry; schedules reboots and recoveries."""

    def __init__(
        self,
        bus: ServoBus,
        policy: FaultPolicy,
        emit: Emit,
        recover: Callable[[ServoRecord, FaultKind], bool],
        request_read: Callable[[str], None],
    ) -> None:
        self.bus = bus
        self.policy = policy
        self.emit = emit
        self.recover = recover
        self.request_read = request_read  # make a telemetry group due now ("thermal", "status", "motion")

    # -- helpers ------------------------------------------------------------------------------------
    def _torque_off(self, rec: ServoRecord) -> None:
        try:
            self.bus.write(rec.servo_id, Register.TORQUE_ENABLE, 0)
        except (BusTimeoutError, BusCorruptError, ServoStatusError):
            pass  # the servo may already have shut down; the status read will tell
        rec.torque_on = False

    def _resume_c(self, rec: ServoRecord) -> float:
        return rec.temperature_limit_c - self.policy.thermal_resume_margin_c

    def derated_profile_velocity(self, rec: ServoRecord) -> int:
        spec = rec.spec
        if spec.drive_mode & DRIVE_MODE_TIME_BASED_PROFILE:
            return max(spec.profile_velocity, TIME_BASED_DERATE_MS)  # longer move time = slower
        cap = self.policy.derate_profile_velocity
        return cap if spec.profile_velocity == 0 else min(spec.profile_velocity, cap)

    def _set_derate(self, rec: ServoRecord, on: bool) -> None:
        if rec.derated == on:
            return
        if not rec.missing:
            value = self.derated_profile_velocity(rec) if on else rec.spec.profile_velocity
            try:
                self.bus.write(rec.servo_id, Register.PROFILE_VELOCITY, value)
            except (BusTimeoutError, BusCorruptError, ServoStatusError):
                return  # retried next telemetry read
        rec.derated = on

    def schedule_reboot(self, rec: ServoRecord, now: float, at_s: float, reason: FaultKind) -> None:
        """Reboot no earlier than ``at_s`` and the exponential back-off (`FaultPolicy.reboot_delay_s` of the
        servo's recent reboots), so a fault that lasts a moment recovers instead of burning the reboot budget."""
        if rec.reboot_at_s is None and not rec.latched:
            recent = sum(1 for t in rec.reboots if t > now - self.policy.reboot_window_s)
            rec.reboot_at_s = max(at_s, now + self.policy.reboot_delay_s(recent))
            rec.reboot_reason = reason
            rec.fault_t_s = now
            if reason in (FaultKind.OVERHEATING, FaultKind.INPUT_VOLTAGE):
                self.request_read("thermal")  # the reboot waits for a temperature/voltage read after the fault

    # -- telemetry handlers -------------------------------------------------------------------------
    def on_status(self, rec: ServoRecord, torque_enable: int, hw_error: int, now: float) -> None:
        """Torque Enable + Hardware Error Status (the Alert bit's detail).

        The usual read (the error bits as last read) builds no IntFlag: no new bits, so only the torque
        handling runs (tests/hardware/test_on_status_fast.py checks it against the former single path on
        random sequences)."""
        masked = hw_error & 0x3D
        old = rec.hardware_error
        if masked == old and type(old) is HardwareErrorBits:  # unchanged: nothing new, no IntFlag to build
            bits, new = old, _NO_BITS
        else:
            bits = HardwareErrorBits(masked)
            new = bits & ~old
        rec.hardware_error = bits
        if masked:
            rec.torque_on = bool(torque_enable)
            if rec.torque_on:  # not in the shutdown mask: we still take torque off
                self._torque_off(rec)
        if new:
            self._on_new_bits(rec, new, bits, now)
        if not masked and not torque_enable and rec.torque_on and rec.in_service:
            self._on_reset(rec, now)

    def _on_new_bits(self, rec: ServoRecord, new: HardwareErrorBits, bits: HardwareErrorBits, now: float) -> None:
        """The reactions to error bits that were not set at the last read."""
        if new & HardwareErrorBits.OVERLOAD:
            rec.faults.add(FaultKind.OVERLOAD)
            self.schedule_reboot(rec, now, now + self.policy.overload_cooldown_s, FaultKind.OVERLOAD)
            self.emit(
                rec.servo_id,
                FaultKind.OVERLOAD,
                f"torque off; reboot after {self.policy.overload_cooldown_s:g} s cool-down, goal re-pinned",
            )
        if new & HardwareErrorBits.OVERHEATING:
            rec.faults.add(FaultKind.OVERHEATING)
            self.schedule_reboot(rec, now, now, FaultKind.OVERHEATING)  # gated on temperature in service()
            self.emit(
                rec.servo_id,
                FaultKind.OVERHEATING,
                f"torque off; reboot once below {self._resume_c(rec):g} C",
            )
        if new & HardwareErrorBits.INPUT_VOLTAGE:
            rec.faults.add(FaultKind.INPUT_VOLTAGE)  # the bit, not a reading: the supply may read fine
            self.schedule_reboot(rec, now, now, FaultKind.INPUT_VOLTAGE)  # gated on voltage in service()
            reading = "" if rec.voltage_v is None else f" (last supply reading {rec.voltage_v:.1f} V)"
            self.emit(
                rec.servo_id,
                FaultKind.INPUT_VOLTAGE,
                f"Input Voltage Error bit{reading}: torque off; reboot with back-off once a fresh reading "
                "is back in range",
            )
        if new & _LATCHING:
            rec.faults.add(FaultKind.HARDWARE_ERROR)
            rec.latched = True
            rec.reboot_at_s = None
            self.emit(
                rec.servo_id,
                FaultKind.HARDWARE_ERROR,
                f"{bits!r}: torque off, latched until Driver.clear_fault({rec.servo_id})",
            )

    def _on_reset(self, rec: ServoRecord, now: float) -> None:
        """Torque dropped without an error bit: the servo was reset (brown-out, power cycle)."""
        self.on_reset_seen(rec, "torque found off", now)

    def on_reset_seen(self, rec: ServoRecord, why: str, now: float) -> None:
        """A servo in service was reset (brown-out, power cycle), as the status read (torque found off, no
        error bit) or the position sentinel (its Indirect Address map gone) shows: re-configured and its goal
        re-pinned (`service`, this cycle)."""
        rec.torque_on = False
        rec.recover_at_s = now
        self.emit(rec.servo_id, FaultKind.RECONNECTED, f"servo reset ({why}): re-configure, re-pin goal")

    def on_thermal(self, rec: ServoRecord, voltage_raw: int, temperature_c: int, now: float) -> None:
        policy = self.policy
        rec.temperature_c = temperature_c
        rec.voltage_v = voltage_raw / 10.0
        rec.telemetry_t_s = now
        rec.thermal.add(now, float(temperature_c))
        limit = float(rec.temperature_limit_c)
        rec.seconds_to_limit = rec.thermal.seconds_to(limit)
        level = thermal_level(temperature_c, limit, rec.seconds_to_limit, policy)
        if level == 2 and FaultKind.THERMAL_TORQUE_OFF not in rec.faults:
            rec.faults.add(FaultKind.THERMAL_TORQUE_OFF)
            self._torque_off(rec)
            eta = "now" if rec.seconds_to_limit in (None, 0.0) else f"in {rec.seconds_to_limit:.0f} s"
            self.emit(
                rec.servo_id,
                FaultKind.THERMAL_TORQUE_OFF,
                f"{temperature_c} C, limit {limit:g} C {eta}: torque off until below "
                f"{limit - policy.thermal_resume_margin_c:g} C",
            )
        elif level >= 1 and FaultKind.THERMAL_DERATE not in rec.faults:
            rec.faults.add(FaultKind.THERMAL_DERATE)
            self._set_derate(rec, True)
            eta = "" if rec.seconds_to_limit is None else f", limit in {rec.seconds_to_limit:.0f} s at this rate"
            self.emit(
                rec.servo_id,
                FaultKind.THERMAL_DERATE,
                f"{temperature_c} C{eta}: Profile Velocity lowered to {self.derated_profile_velocity(rec)}",
            )
        cool = temperature_c <= limit - policy.thermal_resume_margin_c
        if FaultKind.THERMAL_TORQUE_OFF in rec.faults and cool:
            rec.faults.discard(FaultKind.THERMAL_TORQUE_OFF)
            rec.recover_at_s = now
        if (
            level == 0
            and FaultKind.THERMAL_DERATE in rec.faults
            and temperature_c <= limit - policy.thermal_margin_c - 2
        ):
            rec.faults.discard(FaultKind.THERMAL_DERATE)
            if FaultKind.VOLTAGE_LOW not in rec.faults:
                self._set_derate(rec, False)
        self._on_voltage(rec, now)

    def _on_voltage(self, rec: ServoRecord, now: float) -> None:
        if rec.voltage_v is None:
            return
        low = self.policy.voltage_low_v if self.policy.voltage_low_v is not None else rec.info.supply_min_v
        high = self.policy.voltage_high_v if self.policy.voltage_high_v is not None else rec.info.supply_max_v
        state = voltage_state(rec.voltage_v, low, high)
        if state == 0:
            rec.voltage_count = 0
            if FaultKind.VOLTAGE_LOW in rec.faults and not rec.hardware_error & HardwareErrorBits.INPUT_VOLTAGE:
                rec.faults.discard(FaultKind.VOLTAGE_LOW)
                if FaultKind.THERMAL_DERATE not in rec.faults:
                    self._set_derate(rec, False)
            if FaultKind.VOLTAGE_HIGH in rec.faults:
                rec.faults.discard(FaultKind.VOLTAGE_HIGH)
                if not rec.hardware_error:
                    rec.recover_at_s = now
            return
        rec.voltage_count = rec.voltage_count + state if rec.voltage_count * state >= 0 else state
        if abs(rec.voltage_count) < self.policy.voltage_debounce:
            return
        if state < 0 and FaultKind.VOLTAGE_LOW not in rec.faults:
            rec.faults.add(FaultKind.VOLTAGE_LOW)
            self._set_derate(rec, True)
            self.emit(
                rec.servo_id,
                FaultKind.VOLTAGE_LOW,
                f"{rec.voltage_v:.1f} V < {low:g} V: Profile Velocity lowered (less peak current), reported",
            )
        if state > 0 and FaultKind.VOLTAGE_HIGH not in rec.faults:
            rec.faults.add(FaultKind.VOLTAGE_HIGH)
            self._torque_off(rec)
            self.emit(
                rec.servo_id,
                FaultKind.VOLTAGE_HIGH,
                f"{rec.voltage_v:.1f} V > {high:g} V: torque off until back in range",
            )

    def on_motion(self, rec: ServoRecord) -> None:
        """Load back-off: each high reading shrinks the goal's reach from present by ``backoff_gain``;
        each low one (below half the threshold) grows it back, until goals pass through unchanged."""
        fraction = rec.load_fraction
        if fraction is None:
            return
        policy = self.policy
        if abs(fraction) > policy.load_backoff_fraction:
            rec.backoff_scale *= policy.backoff_gain
            if FaultKind.LOAD_BACKOFF not in rec.faults:
                rec.faults.add(FaultKind.LOAD_BACKOFF)
                self.emit(
                    rec.servo_id,
                    FaultKind.LOAD_BACKOFF,
                    f"load {fraction:+.0%} of limit: goals eased toward present "
                    f"(reach x{policy.backoff_gain:g} "
                    "per high reading) until the load drops",
                )
        elif abs(fraction) < 0.5 * policy.load_backoff_fraction and FaultKind.LOAD_BACKOFF in rec.faults:
            rec.backoff_scale = min(1.0, rec.backoff_scale / max(policy.backoff_gain, 1e-3))
            if rec.backoff_scale >= 1.0:
                rec.faults.discard(FaultKind.LOAD_BACKOFF)

    # -- scheduled reboots and recoveries -------------------------------------------------------------
    def _reboot_allowed(self, rec: ServoRecord, now: float) -> bool:
        recent = [t for t in rec.reboots if t > now - self.policy.reboot_window_s]
        return len(recent) < self.policy.max_reboots

    def _reboot_condition_met(self, rec: ServoRecord, now: float) -> bool:
        """The back-off time has passed and, for heat and supply faults, a reading taken after the fault
        is below its threshold (a reboot into a persisting cause would only trip again)."""
        if rec.reboot_at_s is None or now < rec.reboot_at_s:
            return False
        fresh = rec.telemetry_t_s is not None and rec.telemetry_t_s > rec.fault_t_s
        if rec.reboot_reason == FaultKind.OVERHEATING:
            return (
                fresh
                and rec.temperature_c is not None
                and (rec.temperature_c <= rec.temperature_limit_c - self.policy.thermal_resume_margin_c)
            )
        if rec.reboot_reason in (FaultKind.INPUT_VOLTAGE, FaultKind.VOLTAGE_LOW):
            return fresh and rec.voltage_count == 0 and rec.voltage_v is not None
        return True

    def service(self, rec: ServoRecord, now: float) -> None:
        """Run a due reboot or recovery of ``rec`` (at most one bus action per call)."""
        if rec.missing or rec.latched:
            return
        if rec.reboot_at_s is not None and self._reboot_condition_met(rec, now):
            reason = rec.reboot_reason or FaultKind.OVERLOAD
            if not self._reboot_allowed(rec, now):
                rec.latched = True
                rec.reboot_at_s = None
                rec.faults.add(FaultKind.LATCHED)
                self.emit(
                    rec.servo_id,
                    FaultKind.LATCHED,
                    f"{self.policy.max_reboots} reboots within {self.policy.reboot_window_s:g} s: "
                    "torque stays "
                    f"off until Driver.clear_fault({rec.servo_id})",
                )
                return
            try:
                self.bus.reboot(rec.servo_id)
            except (BusTimeoutError, BusCorruptError, ServoStatusError):
                pass  # a rebooting servo may not finish its status packet; recovery verifies
            rec.reboots.append(now)
            rec.reboot_at_s = None
            rec.recover_at_s = now + self.policy.reboot_settle_s
            rec.torque_on = False
            self.emit(rec.servo_id, FaultKind.REBOOTED, f"rebooted to clear {reason.value}")
            return
        if rec.recover_at_s is not None and now >= rec.recover_at_s:
            if self.recover(rec, FaultKind.RECOVERED):
                rec.recover_at_s = None


def event(t_s: float, servo_id: int | None, kind: FaultKind, reaction: str) -> FaultEvent:
    return FaultEvent(t_s, servo_id, kind, reaction)
