"""The moving, heating part of an emulated servo: motion profiles, heat, load, trips, live registers.

A base class of :class:`servoface.hardware.emulator.servo.EmulatedServo`, kept apart so each module holds one idea:
this one integrates the physics lazily between two clock readings and writes the live registers
(Realtime Tick .. Present Temperature) from it; the servo module owns memory access and the write rules.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable

from servoface.hardware.emulator import physics
from servoface.hardware.emulator.control_table import EEPROM_END
from servoface.hardware.emulator.faults import HARDWARE_KINDS, FaultSchedule
from servoface.hardware.emulator.models import (
    ACCELERATION_UNIT_RPM2,
    HW_INPUT_VOLTAGE,
    HW_OVERHEATING,
    HW_OVERLOAD,
    TICKS_PER_REV,
    VELOCITY_UNIT_RPM,
    ModelSpec,
)
from servoface.hardware.emulator.realism import Realism, RealState

VEL_UNIT_TICK_S = VELOCITY_UNIT_RPM / 60.0 * TICKS_PER_REV  # one Present Velocity LSB in ticks/s
ACC_UNIT_TICK_S2 = ACCELERATION_UNIT_RPM2 / 3600.0 * TICKS_PER_REV
POSITION_MODES = (3, 4, 5)
A_TORQUE, A_GOAL_POS, A_HW_ERR, A_WATCHDOG, A_MODE, A_DRIVE = 64, 116, 70, 98, 11, 10
IN_POSITION_TICK = 2.0
STEP_S = physics.STEP_S
THERMAL_DEFER_S = 0.02  # at rest, heat is integrated at most this often (exact: the load is constant)


def _i(mem: bytearray, addr: int, size: int, signed: bool = False) -> int:
    return int.from_bytes(mem[addr : addr + size], "little", signed=signed)


class ServoMotion:
    """Physics state and its lazy integration; the subclass provides memory, identity and power-up."""

    uid: int
    spec: ModelSpec
    mem: bytearray
    motor: physics.MotorState
    obstacle: physics.Obstacle | None
    input_voltage_v: float
    ambient_c: float
    powered: bool
    _clock: Callable[[], float]
    _faults: FaultSchedule
    _profile: physics.MotionProfile
    _t: float
    _accel: float
    _live_dirty: bool
    _thermal_t: float
    _plan_key: tuple[object, ...]
    _last_rx_s: float
    _watchdog_tripped: bool
    _reports_load: bool
    _stall_units: float
    _real: RealState | None

    def _init_motion(self, spec: ModelSpec, clock: Callable[[], float], realism: Realism | None = None) -> None:
        self.ambient_c = 25.0
        self.input_voltage_v = spec.nominal_voltage_v
        self.obstacle = None
        self.powered = True
        self.motor = physics.MotorState()
        self._profile = physics.MotionProfile(spec.no_load_speed_tick_s, math.inf)
        self._t = clock()
        self._accel = 0.0
        self._live_dirty = True
        self._thermal_t = self._t
        self._plan_key = ()
        self._reports_load = spec.present_kind == "load"
        self._stall_units = spec.stall_current_a * 1000.0 / spec.current_unit_ma
        self._last_rx_s = self._t
        self._watchdog_tripped = False
        self._real = None if realism is None else RealState.create(realism, self.uid, self.motor.pos)

    @property
    def physical_tick(self) -> float:
        """Where the output shaft physically is (raw ticks): the ideal position, or the non-ideal one."""
        return self.motor.pos if self._real is None else self._real.pos

    def _power_on(self, keep: bytes | None) -> None:
        raise NotImplementedError  # provided by EmulatedServo

    def _start_move(self) -> None:
        """Aim at Goal Position with the current profile registers (re-planned only when they changed)."""
        mem = self.mem
        motor = self.motor
        v_limit_reg, max_pos, min_pos = LIMITS.unpack_from(mem, 44)
        prof_a, prof_v, goal = _GOALS.unpack_from(mem, 108)
        mode = mem[A_MODE]
        drive = mem[A_DRIVE]
        offset = _I32.unpack_from(mem, 20)[0]
        key = (goal, prof_a, prof_v, mode, drive, v_limit_reg, max_pos, min_pos, self.input_voltage_v, offset)
        if key == self._plan_key and not drive & 0x04:
            return  # same goal and profile again (typical of a periodic sync write): nothing to re-plan
        self._plan_key = key
        if mode == 3:
            goal = min(max(goal, min_pos), max_pos)
        if mode in POSITION_MODES:
            raw = goal - offset
            motor.target = 4095.0 - raw if drive & 1 else float(raw)
        v_cap = self.spec.no_load_speed_tick_s * max(0.0, self.input_voltage_v / self.spec.nominal_voltage_v)
        v_limit = v_limit_reg * VEL_UNIT_TICK_S
        if v_limit > 0:
            v_cap = min(v_cap, v_limit)
        if drive & 0x04:
            self._profile = physics.time_based_profile(motor.target - motor.pos, prof_v, prof_a, v_cap)
        else:
            v = prof_v * VEL_UNIT_TICK_S if prof_v else v_cap
            a = prof_a * ACC_UNIT_TICK_S2 if prof_a else math.inf
            v = min(v, v_cap)
            profile = self._profile  # a new goal under the same profile registers: the same limits again
            if profile.v_max != v or profile.a_max != a:
                self._profile = physics.MotionProfile(v, a)

    # ----------------------------------------------------------------- physics
    def heard(self, t_s: float) -> None:
        """An instruction packet reached this servo at ``t_s`` (feeds the Bus Watchdog)."""
        if self.mem[A_WATCHDOG] and t_s > self._t:
            self.advance(t_s)  # a trip due before this packet must happen first
        if t_s > self._last_rx_s:
            self._last_rx_s = t_s

    def advance(self, t_s: float | None = None) -> None:
        """Bring the physics up to ``t_s`` (default: now)."""
        real = self._real
        if real is None:
            if t_s is None or t_s > self._t:  # else nothing to integrate (the common repeat call)
                self._advance_ideal(t_s)
            return
        t0 = self._t
        self._advance_ideal(t_s)
        if self._t > t0:
            motor = self.motor
            real.update(motor.pos, motor.vel, motor.load, self._t - t0)
            self._live_dirty = True

    def _advance_ideal(self, t_s: float | None) -> None:
        t1 = self._clock() if t_s is None else t_s
        t0 = self._t
        if t1 <= t0:
            return
        self._t = t1
        faults = self._faults
        if faults.any and faults.has_any(self.uid):
            self._apply_faults(t0, t1)
        mem = self.mem
        motor = self.motor
        wd = mem[A_WATCHDOG]
        if 0 < wd < 128 and mem[A_TORQUE] and t1 - self._last_rx_s > wd * 0.02:
            self._watchdog_tripped = True
            mem[A_WATCHDOG] = 0xFF
            motor.target = motor.pos
            self._plan_key = ()
        torque = mem[A_TORQUE] == 1
        mode = mem[A_MODE]
        if torque and mode not in POSITION_MODES:
            self._settle_thermal(t0)
            self._drive_velocity(t1 - t0)
            self._thermal(t1 - t0, 0.1)
            self._thermal_t = t1
            self._live_dirty = True
            return
        if not torque or (motor.vel == 0.0 and motor.pos == motor.target):
            if not torque:
                load = 0.0
            elif self.obstacle is None:
                load = physics.HOLD_LOAD
            else:
                load = physics.load_fraction(motor, torque, self.obstacle, 0.0)
            if load != motor.load:
                self._settle_thermal(t0)
                motor.load = load
                self._live_dirty = True
            if t1 - self._thermal_t >= THERMAL_DEFER_S:
                self._settle_thermal(t1)  # constant load at rest: integrating later is exact
            return
        self._settle_thermal(t0)
        self._live_dirty = True
        t = t0
        profile, obstacle = self._profile, self.obstacle
        step_motion, load_fraction, thermal = physics.step_motion, physics.load_fraction, self._thermal
        free = obstacle is None  # no wall: `free_load` gives `load_fraction`'s value without its checks
        free_load = physics.free_load
        while t < t1:
            dt = min(STEP_S, t1 - t)
            v0 = motor.vel
            step_motion(motor, profile, dt, obstacle)
            vel = motor.vel
            accel = self._accel = (vel - v0) / dt
            if free:
                load = free_load(vel, motor.target - motor.pos, accel)
            else:
                load = load_fraction(motor, True, obstacle, accel)
            motor.load = load
            thermal(dt, load)
            t += dt
            if not mem[A_TORQUE]:
                motor.load = 0.0
                break
            if vel == 0.0 and motor.pos == motor.target:  # `motor.at_rest`, inlined
                if free:
                    motor.load = free_load(0.0, 0.0, 0.0)
                else:
                    motor.load = load_fraction(motor, True, obstacle, 0.0)
                if t1 - t > 0:  # `_thermal` of a zero step does nothing
                    thermal(t1 - t, motor.load)
                t = t1
                break
            if not free and physics.blocked_by(motor, obstacle) and t < t1:
                # stalled: constant load until the end (or until a trip drops torque)
                rest = t1 - t
                chunk = min(rest, 0.05)
                while rest > 0 and mem[A_TORQUE]:
                    self._thermal(chunk, load)
                    t += chunk
                    rest -= chunk
                    chunk = min(rest, 0.05)
                if not mem[A_TORQUE]:
                    motor.load = 0.0
                break
        self._thermal_t = min(t, t1)

    def _settle_thermal(self, t_s: float) -> None:
        """Integrate heat up to ``t_s`` at the present (constant) load."""
        dt = t_s - self._thermal_t
        if dt > 0:
            self._thermal(dt, self.motor.load)
            self._thermal_t = t_s
            self._live_dirty = True

    def _drive_velocity(self, dt: float) -> None:
        mem = self.mem
        mode = mem[A_MODE]
        v_nl = self.spec.no_load_speed_tick_s
        if mode == 1:
            v = _i(mem, 104, 4, True) * VEL_UNIT_TICK_S
        elif mode == 16:
            v = _i(mem, 100, 2, True) / 885.0 * v_nl
        else:
            limit = max(1, _i(mem, 38, 2))
            v = max(-1.0, min(1.0, _i(mem, 102, 2, True) / limit)) * v_nl
        if self.mem[A_DRIVE] & 1:
            v = -v
        if self._watchdog_tripped:
            v = 0.0
        new_pos = self.motor.pos + v * dt
        if self.obstacle is not None and (new_pos - self.obstacle[0]) * self.obstacle[1] < 0:
            new_pos, v = self.obstacle[0], 0.0
        self.motor.pos = self.motor.target = new_pos
        self.motor.vel = v

    def _thermal(self, dt: float, load: float) -> None:
        if dt <= 0:
            return
        motor = self.motor
        motor.temperature_c = physics.step_thermal(motor.temperature_c, self.ambient_c, load, dt)
        if abs(load) >= physics.OVERLOAD_LOAD:
            motor.overload_s += dt
            if motor.overload_s >= physics.OVERLOAD_TRIP_S:
                self._trip(HW_OVERLOAD)
        else:
            motor.overload_s = 0.0
        if motor.temperature_c >= self.mem[31]:
            self._trip(HW_OVERHEATING)

    def _trip(self, bits: int) -> None:
        self._live_dirty = True
        mem = self.mem
        mem[A_HW_ERR] |= bits
        if bits & mem[63] and mem[A_TORQUE]:
            mem[A_TORQUE] = 0
            self.motor.target = self.motor.pos
            self._plan_key = ()
            self.motor.vel = 0.0
            self.motor.load = 0.0

    def _voltage_ok(self) -> bool:
        decivolts = self.input_voltage_v * 10.0
        return _i(self.mem, 34, 2) <= decivolts <= _i(self.mem, 32, 2)

    def _recheck_causes(self) -> None:
        """After power-up: errors whose cause persists come straight back."""
        if not self._voltage_ok():
            self._trip(HW_INPUT_VOLTAGE)
        if self.motor.temperature_c >= self.mem[31]:
            self._trip(HW_OVERHEATING)
        for kind, bit in HARDWARE_KINDS.items():
            if self._faults.active(self.uid, kind, self._t):
                self._trip(bit)

    def _apply_faults(self, t0: float, t1: float) -> None:
        for f in self._faults.overlapping(self.uid, t0, t1):
            bit = HARDWARE_KINDS.get(f.kind)
            if bit is not None:
                self._trip(bit)
            elif f.kind == "disconnect":
                if f.start_s <= t1 and self.powered and f.end_s > t1:
                    self.powered = False
                    self.mem[A_TORQUE] = 0
                    self.motor.target = self.motor.pos
                    self._plan_key = ()
                    self.motor.vel = 0.0
                if t0 < f.end_s <= t1:
                    self.powered = True
                    self._power_on(keep=bytes(self.mem[:EEPROM_END]))

    def _sync_live(self) -> None:
        """Write the live (read-only) registers 120..146 from the physics state into memory (one pack)."""
        mem = self.mem
        real = self._real
        if not self._live_dirty and real is None:
            _TICK.pack_into(mem, 120, int(self._t * 1000.0) % 32768)  # at rest only the clock moves
            return
        self._live_dirty = False
        motor = self.motor
        vel = motor.vel
        rev = mem[A_DRIVE] & 1
        offset = _I32.unpack_from(mem, 20)[0]
        prof_a, prof_v = _PROFILE.unpack_from(mem, 108)
        pos = motor.pos if real is None else real.pos
        if rev:
            present = 4095.0 - pos + offset
            target = 4095.0 - motor.target + offset
            load = -motor.load
            vel = -vel
        else:
            present = pos + offset
            target = motor.target + offset
            load = motor.load
        moving = vel != 0.0
        status = (1 if abs(motor.target - motor.pos) <= IN_POSITION_TICK else 0) | (2 if moving else 0)
        if prof_v:
            status |= 0x30 if prof_a else 0x10
        present_load = load * (1000.0 if self._reports_load else self._stall_units)
        if real is not None:
            present_load *= real.current_scale(motor.temperature_c)
            present = real.read_tick(present)
        vel_units = round(vel / VEL_UNIT_TICK_S)
        values = (
            int(self._t * 1000.0) % 32768,
            1 if moving else 0,
            status,
            round(load * 885),
            round(present_load),
            vel_units,
            round(present),
            vel_units,
            round(target),
            round(self.input_voltage_v * 10),
            round(motor.temperature_c),
        )
        try:
            _LIVE.pack_into(mem, 120, *values)
        except struct.error:  # something out of its register's range (runaway test values): saturate
            _LIVE.pack_into(mem, 120, *(_saturate(v, lo, hi) for v, (lo, hi) in zip(values, _LIVE_RANGES, strict=True)))


_LIVE = struct.Struct("<HBBhhiiiiHB")  # Realtime Tick (120) .. Present Temperature (146)
_TICK = struct.Struct("<H")
_I32 = struct.Struct("<i")
_PROFILE = struct.Struct("<II")  # Profile Acceleration (108), Profile Velocity (112)
_LIVE_RANGES = (
    [(0, 65535), (0, 255), (0, 255), (-32768, 32767), (-32768, 32767)]
    + [(-(1 << 31), (1 << 31) - 1)] * 4
    + [
        (0, 65535),
        (0, 255),
    ]
)


def _saturate(v: int, lo: int, hi: int) -> int:
    return lo if v < lo else hi if v > hi else v


LIMITS = struct.Struct("<III")  # Velocity Limit (44), Max (48) / Min (52) Position Limit
_GOALS = struct.Struct("<IIi")  # Profile Acceleration (108), Profile Velocity (112), Goal Position (116)
