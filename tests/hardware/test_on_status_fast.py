"""`FaultReactions.on_status`'s unchanged-bits path against the full path (a copy of the logic before it).

Random sequences of Torque Enable / Hardware Error Status readings, with the record's torque, latch,
reboot and recovery state shuffled between readings, give the same records, bus writes and events.
"""

from __future__ import annotations

import copy
import dataclasses
import random
from typing import Any

from servoface.hardware.errors import BusTimeoutError
from servoface.hardware.fault_policy import FaultPolicy, ThermalTrend
from servoface.hardware.fault_reactions import _LATCHING, FaultReactions
from servoface.hardware.registers import HardwareErrorBits, Register
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.servo_record import ServoRecord
from servoface.hardware.snapshot import FaultKind


class _Bus:
    def __init__(self, fail: bool) -> None:
        self.writes: list[tuple[int, Register, int]] = []
        self.fail = fail

    def write(self, servo_id: int, register: Register, value: int) -> None:
        self.writes.append((servo_id, register, value))
        if self.fail:
            raise BusTimeoutError("no reply", (servo_id,))


class _Reference(FaultReactions):
    """``on_status`` as it was before the unchanged-bits path."""

    def on_status(self, rec: ServoRecord, torque_enable: int, hw_error: int, now: float) -> None:
        bits = HardwareErrorBits(hw_error & 0x3D)
        new = bits & ~rec.hardware_error
        rec.hardware_error = bits
        if bits:
            rec.torque_on = bool(torque_enable)
            if rec.torque_on:
                self._torque_off(rec)
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
            self.schedule_reboot(rec, now, now, FaultKind.OVERHEATING)
            self.emit(rec.servo_id, FaultKind.OVERHEATING, f"torque off; reboot once below {self._resume_c(rec):g} C")
        if new & HardwareErrorBits.INPUT_VOLTAGE:
            rec.faults.add(FaultKind.INPUT_VOLTAGE)
            self.schedule_reboot(rec, now, now, FaultKind.INPUT_VOLTAGE)
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
        if not bits and not torque_enable and rec.torque_on and rec.in_service:
            rec.torque_on = False
            rec.recover_at_s = now
            self.emit(rec.servo_id, FaultKind.RECONNECTED, "servo reset (torque found off): re-configure, re-pin goal")


def _record() -> ServoRecord:
    spec = ServoSpec(7, "XL330-M288", role="r7", min_position_tick=1024, max_position_tick=3072)
    return ServoRecord(spec, spec.model_info, ThermalTrend(10.0), 70, voltage_v=5.0)


def _reactions(cls: type[FaultReactions], fail: bool) -> tuple[FaultReactions, _Bus, list[Any], list[Any]]:
    bus = _Bus(fail)
    events: list[Any] = []
    reads: list[Any] = []
    reactions = cls(
        bus,  # type: ignore[arg-type]
        FaultPolicy(),
        lambda sid, kind, why: events.append((sid, kind, why)),
        lambda rec, kind: True,
        reads.append,
    )
    return reactions, bus, events, reads


def _state(rec: ServoRecord) -> dict[str, object]:
    """Every field (the thermal trend is a fresh one each record: left out), and the error's type."""
    fields = {f.name: getattr(rec, f.name) for f in dataclasses.fields(rec) if f.name not in ("thermal", "_frozen")}
    fields["reboots"] = tuple(rec.reboots)
    fields["error_type"] = type(rec.hardware_error)
    return fields


def test_on_status_matches_the_full_path_on_random_sequences() -> None:
    rng = random.Random(17)
    errors = [0, 0, 0, 0x01, 0x04, 0x08, 0x10, 0x20, 0x24, 0x3D, 0xFF, 0x02, 0x40, 0x80, 0xC2]
    steps = 0
    fast_steps = 0
    for trial in range(300):
        fail = trial % 3 == 0
        fast, fast_bus, fast_events, fast_reads = _reactions(FaultReactions, fail)
        ref, ref_bus, ref_events, ref_reads = _reactions(_Reference, fail)
        rec = _record()
        other = _record()
        now = 0.0
        hw = rng.choice(errors)
        for _ in range(rng.randrange(1, 40)):
            now += rng.choice((0.0, 0.1, 0.5, 3.0))
            if rng.random() < 0.3:  # keep the last reading (the usual case) or change it
                hw = rng.choice(errors)
            torque = rng.choice((0, 1, 1))
            if rng.random() < 0.2:  # the driver's other handlers change the record in between
                change: dict[str, Any] = rng.choice(
                    (
                        {"torque_on": rng.random() < 0.5},
                        {"latched": False},
                        {"reboot_at_s": None},
                        {"recover_at_s": None},
                        {"missing": rng.random() < 0.2},
                        {"hardware_error": HardwareErrorBits.NONE},  # as `_recover` resets it
                    )
                )
                for name, value in change.items():
                    setattr(rec, name, value)
                    setattr(other, name, copy.copy(value))
            was = rec.hardware_error
            fast_steps += (hw & 0x3D) == was
            fast.on_status(rec, torque, hw, now)
            ref.on_status(other, torque, hw, now)
            steps += 1
            assert _state(rec) == _state(other)
            assert rec.hardware_error is other.hardware_error or rec.hardware_error == other.hardware_error
            assert fast_bus.writes == ref_bus.writes
            assert fast_events == ref_events
            assert fast_reads == ref_reads
    assert fast_steps > steps // 3  # the unchanged path was exercised, and so was the other
    assert fast_steps < steps


def test_a_reset_servo_is_still_found_on_the_unchanged_path() -> None:
    """No error bits before or now, torque found off while in service: the reset reaction (fails if the
    unchanged path returned without it)."""
    reactions, _bus, events, _reads = _reactions(FaultReactions, False)
    rec = _record()
    rec.torque_on = True
    reactions.on_status(rec, 1, 0, 1.0)
    assert events == [] and rec.torque_on
    reactions.on_status(rec, 0, 0, 2.0)
    assert [e[1] for e in events] == [FaultKind.RECONNECTED]
    assert not rec.torque_on and rec.recover_at_s == 2.0


def test_a_persisting_error_with_torque_on_is_taken_off_again() -> None:
    reactions, bus, events, _reads = _reactions(FaultReactions, False)
    rec = _record()
    rec.torque_on = True
    reactions.on_status(rec, 1, 0x20, 1.0)
    assert [e[1] for e in events] == [FaultKind.OVERLOAD]
    bus.writes.clear()
    reactions.on_status(rec, 1, 0x20, 2.0)  # same bits: no new event, but torque off again
    assert len(events) == 1
    assert bus.writes == [(7, Register.TORQUE_ENABLE, 0)] and not rec.torque_on
