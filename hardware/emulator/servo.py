"""One emulated servo: its control-table memory, write rules (error byte) and lazily advanced physics."""

from __future__ import annotations

import math
import struct
import threading
from collections.abc import Callable
from functools import wraps
from typing import Any, TypeVar

from hardware.emulator import physics
from hardware.emulator.control_table import EEPROM_END, Register
from hardware.emulator.errors import EmulatorConfigError
from hardware.emulator.faults import HARDWARE_KINDS, FaultSchedule
from hardware.emulator.models import (
    ACCELERATION_UNIT_RPM2,
    BAUD_CODES,
    HW_INPUT_VOLTAGE,
    HW_OVERHEATING,
    HW_OVERLOAD,
    TICKS_PER_REV,
    VELOCITY_UNIT_RPM,
    ModelSpec,
)
from hardware.emulator.packet import ErrorNumber

VEL_UNIT_TICK_S = VELOCITY_UNIT_RPM / 60.0 * TICKS_PER_REV  # one Present Velocity LSB in ticks/s
ACC_UNIT_TICK_S2 = ACCELERATION_UNIT_RPM2 / 3600.0 * TICKS_PER_REV
POSITION_MODES = (3, 4, 5)
A_TORQUE, A_GOAL_POS, A_HW_ERR, A_WATCHDOG, A_MODE, A_DRIVE = 64, 116, 70, 98, 11, 10
IN_POSITION_TICK = 2.0
THERMAL_DEFER_S = 0.02  # at rest, heat is integrated at most this often (exact: the load is constant)


_F = TypeVar("_F", bound=Callable[..., Any])


def _locked(method: _F) -> _F:
    """Run a test hook under the chain's lock (the pty thread may be serving the same servo)."""

    @wraps(method)
    def wrapper(self: EmulatedServo, *args: Any, **kwargs: Any) -> Any:
        with self._lock:
            return method(self, *args, **kwargs)

    return wrapper  # type: ignore[return-value]


def _i(mem: bytearray, addr: int, size: int, signed: bool = False) -> int:
    return int.from_bytes(mem[addr : addr + size], "little", signed=signed)


def _put(mem: bytearray, addr: int, size: int, value: int) -> None:
    mem[addr : addr + size] = (int(value) & ((1 << (8 * size)) - 1)).to_bytes(size, "little")


class EmulatedServo:
    """A servo on the emulated chain. Test hooks (``read_register``/``write_register``/``move_by_hand``)
    bypass the wire; the ``wire_*`` methods implement what a packet may do, returning error numbers.
    """

    def __init__(
        self,
        uid: int,
        spec: ModelSpec,
        *,
        baud_code: int,
        clock: Callable[[], float],
        faults: FaultSchedule,
        lock: threading.RLock | None = None,
    ) -> None:
        self.uid = uid
        self._lock = lock if lock is not None else threading.RLock()
        self.spec = spec
        self.table = spec.table
        self._clock = clock
        self._faults = faults
        self.ambient_c = 25.0
        self.input_voltage_v = spec.nominal_voltage_v
        self.obstacle: physics.Obstacle | None = None
        self.registered: tuple[int, bytes] | None = None
        self.silent_until_s = -math.inf
        self.on_change: Callable[[EmulatedServo], None] | None = None  # chain hook: id/baud/silence changed
        self.powered = True
        self.mem = bytearray()
        self.motor = physics.MotorState()
        self._profile = physics.MotionProfile(spec.no_load_speed_tick_s, math.inf)
        self._t = clock()
        self._accel = 0.0
        self._live_dirty = True
        self._thermal_t = self._t
        self._plan_key: tuple[object, ...] = ()
        # (first Indirect Data address, first Indirect Address address, count) per indirect block
        self._indirect: list[tuple[int, int, int]] = _indirect_blocks(spec)
        self._indirect_lo = min((d for d, _, _ in self._indirect), default=1 << 30)
        self._indirect_hi = max((d + n for d, _, n in self._indirect), default=0)
        self._reports_load = spec.present_kind == "load"
        self._stall_units = spec.stall_current_a * 1000.0 / spec.current_unit_ma
        self._last_rx_s = self._t
        self._watchdog_tripped = False
        self._power_on(keep=None)
        self.mem[7] = uid
        self.mem[8] = baud_code

    # ----------------------------------------------------------------- identity and settings
    @property
    def id(self) -> int:
        return self.mem[7]

    @property
    def baud_bps(self) -> int:
        return BAUD_CODES.get(self.mem[8], 0)

    @property
    def return_delay_s(self) -> float:
        return self.mem[9] * 2e-6

    @property
    def status_return_level(self) -> int:
        return self.mem[68]

    @property
    def torque_on(self) -> bool:
        return self.mem[A_TORQUE] == 1

    @property
    def hardware_error(self) -> int:
        return self.mem[A_HW_ERR]

    @property
    def operating_mode(self) -> int:
        return self.mem[A_MODE]

    @property
    def reversed(self) -> bool:
        return bool(self.mem[A_DRIVE] & 1)

    @property
    def homing_offset_tick(self) -> int:
        return _i(self.mem, 20, 4, True)

    # ----------------------------------------------------------------- frames
    def _to_present(self, shaft: float) -> float:
        return (4095.0 - shaft if self.reversed else shaft) + self.homing_offset_tick

    def _to_shaft(self, present: float) -> float:
        raw = present - self.homing_offset_tick
        return 4095.0 - raw if self.reversed else raw

    # ----------------------------------------------------------------- test hooks (bypass the wire)
    @property
    def position_tick(self) -> int:
        """Present Position now (ticks)."""
        with self._lock:
            self.advance()
            return round(self._to_present(self.motor.pos))

    @property
    def shaft_tick(self) -> float:
        """Physical shaft angle in ticks (differs from Present Position by homing offset and reverse)."""
        with self._lock:
            self.advance()
            return self.motor.pos

    @property
    def temperature_c(self) -> float:
        """Winding temperature now (degC); settable for tests."""
        with self._lock:
            self.advance()
            self._settle_thermal(self._t)
            return self.motor.temperature_c

    @temperature_c.setter
    def temperature_c(self, value: float) -> None:
        with self._lock:
            self.advance()
            self._settle_thermal(self._t)
            self.motor.temperature_c = float(value)
            self._live_dirty = True

    @property
    def load_fraction(self) -> float:
        """Signed load as a fraction of stall torque now."""
        with self._lock:
            self.advance()
            return self.motor.load

    @_locked
    def read_register(self, key: str | int) -> int:
        """Value of a register (by name or start address), live values brought up to now."""
        reg = self.table.get(key)
        self.advance()
        self._sync_live()
        return reg.decode(self.mem[reg.address : reg.end])

    @_locked
    def write_register(self, key: str | int, value: int) -> None:
        """Set a register directly, with the write's side effects but no access/range checks."""
        reg = self.table.get(key)
        self.advance()
        self._apply(reg.address, reg.encode(int(value)))

    @_locked
    def move_by_hand(self, present_tick: float) -> None:
        """Turn the horn by hand to where Present Position reads ``present_tick`` (only with torque off)."""
        self.advance()
        if self.torque_on:
            raise EmulatorConfigError(
                f"servo {self.id}: move_by_hand needs torque off (the motor holds its goal)"
            )
        self.motor.pos = self.motor.target = self._to_shaft(float(present_tick))
        self._plan_key = ()
        self._live_dirty = True
        self.motor.vel = 0.0

    @_locked
    def set_obstacle(self, present_tick: float | None) -> None:
        """A rigid stop at ``present_tick`` on the side away from the current position (None removes it)."""
        self.advance()
        if present_tick is None:
            self.obstacle = None
            return
        wall = self._to_shaft(float(present_tick))
        side = 1.0 if self.motor.pos >= wall else -1.0
        self.obstacle = (wall, side)

    # ----------------------------------------------------------------- power
    def _power_on(self, keep: bytes | None) -> None:
        """Power-up state: RAM defaults; EEPROM from ``keep`` (None = model defaults)."""
        self._live_dirty = True
        image = self.table.defaults_image()
        if keep is not None:
            image[:EEPROM_END] = keep[:EEPROM_END]
        self.mem = image
        self.registered = None
        self._watchdog_tripped = False
        self.motor.vel = 0.0
        self.motor.target = self.motor.pos
        self._plan_key = ()
        self.motor.overload_s = 0.0
        _put(self.mem, A_GOAL_POS, 4, round(self._to_present(self.motor.pos)))
        self._recheck_causes()
        self._sync_live()

    @_locked
    def reboot(self, silence_s: float = 0.0) -> None:
        """Reboot: RAM back to defaults (torque off, errors cleared unless their cause persists)."""
        self.advance()
        self._power_on(keep=bytes(self.mem[:EEPROM_END]))
        self.silent_until_s = self._t + silence_s
        self._changed()

    @_locked
    def factory_reset(self, option: int) -> None:
        """Factory Reset: 0xFF everything (ID 1, 57 600 bps), 0x01 all but ID, 0x02 all but ID and baud."""
        self.advance()
        old = bytes(self.mem[:EEPROM_END])
        self._power_on(keep=None)
        if option in (0x01, 0x02):
            self.mem[7] = old[7]
        if option == 0x02:
            self.mem[8] = old[8]
        self._changed()

    def _changed(self) -> None:
        if self.on_change is not None:
            self.on_change(self)

    @_locked
    def clear_multi_turn(self) -> None:
        """Clear: bring Present Position back into one turn (0..4095), keeping the shaft where it is."""
        self.advance()
        present = self._to_present(self.motor.pos)
        turns = (round(present) // TICKS_PER_REV) * TICKS_PER_REV
        shift = -turns if not self.reversed else turns
        self.motor.pos += shift
        self.motor.target += shift
        self._plan_key = ()

    # ----------------------------------------------------------------- reads
    def read_bytes(self, address: int, length: int) -> tuple[int, bytes]:
        """(error number, data) for a Read of ``length`` bytes at ``address``."""
        size = self.table.size
        if address + length > size or length < 0:
            return ErrorNumber.ACCESS, b""
        self.advance()
        end = address + length
        if address < 147 and end > 120:
            self._sync_live()
        if self._indirect_lo < end and address < self._indirect_hi:
            return 0, self._read_indirect(address, length)
        return 0, bytes(self.mem[address:end])

    # ----------------------------------------------------------------- indirect addressing
    def _indirect_target(self, address: int) -> int | None:
        """The address Indirect Data byte ``address`` stands for (None if it is not an Indirect Data byte)."""
        for data_start, addr_start, count in self._indirect:
            if data_start <= address < data_start + count:
                slot = addr_start + 2 * (address - data_start)
                return self.mem[slot] | self.mem[slot + 1] << 8
        return None

    def _read_indirect(self, address: int, length: int) -> bytes:
        targets = [self._indirect_target(a) for a in range(address, address + length)]
        if any(t is not None and 120 <= t < 147 for t in targets):
            self._sync_live()
        mem = self.mem
        return bytes(
            mem[a] if t is None else mem[t]
            for a, t in zip(range(address, address + length), targets, strict=True)
        )

    def _indirect_runs(self, address: int, data: bytes) -> list[tuple[int, bytes]]:
        """Split a write into contiguous runs of real addresses (Indirect Data bytes mapped to targets)."""
        runs: list[tuple[int, bytearray]] = []
        for i, byte in enumerate(data):
            a = address + i
            t = self._indirect_target(a)
            real = a if t is None else t
            if runs and runs[-1][0] + len(runs[-1][1]) == real:
                runs[-1][1].append(byte)
            else:
                runs.append((real, bytearray((byte,))))
        return [(start, bytes(chunk)) for start, chunk in runs]

    # ----------------------------------------------------------------- writes
    def check_write(self, address: int, data: bytes) -> int:
        """Error number a Write of ``data`` at ``address`` would get (0 = accepted); changes nothing."""
        n = len(data)
        if n == 0:
            return ErrorNumber.DATA_LENGTH
        owner = self.table.owner
        if address < 0 or address + n > len(owner):
            return ErrorNumber.ACCESS
        a = address
        end = address + n
        torque = self.torque_on
        while a < end:
            reg = owner[a]
            if reg is None or reg.access != "RW":
                return ErrorNumber.ACCESS
            if reg.address != a or reg.end > end:
                return ErrorNumber.DATA_LENGTH
            if torque and a < EEPROM_END:
                return ErrorNumber.ACCESS
            err = self._check_value(reg, reg.decode(data[a - address : reg.end - address]))
            if err:
                return err
            a = reg.end
        return 0

    def _check_value(self, reg: Register, value: int) -> int:
        if not reg.in_range(value):
            return ErrorNumber.DATA_RANGE
        a = reg.address
        mem = self.mem
        if a == A_MODE and value not in self.spec.operating_modes:
            return ErrorNumber.DATA_RANGE
        if a == A_GOAL_POS:
            if self._watchdog_tripped:
                return ErrorNumber.DATA_RANGE
            if mem[A_MODE] == 3:
                _, max_pos, min_pos = _LIMITS.unpack_from(mem, 44)
                if not min_pos <= value <= max_pos:
                    return ErrorNumber.DATA_LIMIT
        elif a == 104:
            if self._watchdog_tripped:
                return ErrorNumber.DATA_RANGE
            if abs(value) > _i(mem, 44, 4):
                return ErrorNumber.DATA_LIMIT
        elif a == 100 and abs(value) > _i(mem, 36, 2):
            return ErrorNumber.DATA_LIMIT
        elif a == 102 and abs(value) > _i(mem, 38, 2):
            return ErrorNumber.DATA_LIMIT
        elif a == A_TORQUE and value == 1 and self.mem[A_HW_ERR] & self.mem[63]:
            return ErrorNumber.RESULT_FAIL  # latched shutdown error: only Reboot restores torque
        return 0

    def wire_write(self, address: int, data: bytes) -> int:
        """Check then apply a Write from the bus; returns its error number."""
        self.advance()
        if self._indirect_lo < address + len(data) and address < self._indirect_hi:
            return self._write_indirect(address, data)
        err = self.check_write(address, data)
        if not err:
            self._apply(address, data)
        return err

    def _write_indirect(self, address: int, data: bytes) -> int:
        """A write touching Indirect Data goes to the mapped registers (all checked before any change)."""
        runs = self._indirect_runs(address, data)
        for start, chunk in runs:
            err = self.check_write(start, chunk)
            if err:
                return err
        for start, chunk in runs:
            self._apply(start, chunk)
        return 0

    def _apply(self, address: int, data: bytes) -> None:
        """Store ``data`` and run side effects of the registers it covers (no checks)."""
        mem = self.mem
        end = address + len(data)
        self._live_dirty = True
        old_torque = mem[A_TORQUE]
        old_mode = mem[A_MODE]
        mem[address:end] = data
        if address <= A_MODE < end and mem[A_MODE] != old_mode:
            _put(mem, 108, 4, 0)
            _put(mem, 112, 4, 0)
            _put(mem, 100, 2, _i(mem, 36, 2))
            if 102 in self.table:
                _put(mem, 102, 2, _i(mem, 38, 2))
        if address < 9 and end > 7:
            self._changed()
        if address <= A_WATCHDOG < end:
            self._watchdog_tripped = False
            self._last_rx_s = self._t
        if address <= A_TORQUE < end:
            if mem[A_TORQUE] and not old_torque:
                self._start_move()
            elif not mem[A_TORQUE]:
                self.motor.target = self.motor.pos
                self._plan_key = ()
                self.motor.vel = 0.0
        if mem[A_TORQUE] and ((address < 120 and end > 100) or (address < 56 and end > 44)):
            self._start_move()

    def _start_move(self) -> None:
        """Aim at Goal Position with the current profile registers (re-planned only when they changed)."""
        mem = self.mem
        motor = self.motor
        v_limit_reg, max_pos, min_pos = _LIMITS.unpack_from(mem, 44)
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
            self._profile = physics.MotionProfile(min(v, v_cap), a)

    # ----------------------------------------------------------------- physics
    def heard(self, t_s: float) -> None:
        """An instruction packet reached this servo at ``t_s`` (feeds the Bus Watchdog)."""
        if self.mem[A_WATCHDOG]:
            self.advance(t_s)  # a trip due before this packet must happen first
        if t_s > self._last_rx_s:
            self._last_rx_s = t_s

    def advance(self, t_s: float | None = None) -> None:
        """Bring the physics up to ``t_s`` (default: now)."""
        t1 = self._clock() if t_s is None else t_s
        t0 = self._t
        if t1 <= t0:
            return
        self._t = t1
        if self._faults.has_any(self.uid):
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
        while t < t1:
            dt = min(physics.STEP_S, t1 - t)
            v0 = motor.vel
            physics.step_motion(motor, self._profile, dt, self.obstacle)
            self._accel = (motor.vel - v0) / dt
            load = physics.load_fraction(motor, True, self.obstacle, self._accel)
            motor.load = load
            self._thermal(dt, load)
            t += dt
            if not mem[A_TORQUE]:
                motor.load = 0.0
                break
            if motor.at_rest:
                motor.load = physics.load_fraction(motor, True, self.obstacle, 0.0)
                self._thermal(t1 - t, motor.load)
                t = t1
                break
            if physics.blocked_by(motor, self.obstacle) and t < t1:
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
        if self.reversed:
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

    @_locked
    def set_input_voltage(self, volts: float) -> None:
        self.advance()
        self.input_voltage_v = float(volts)
        self._live_dirty = True
        if not self._voltage_ok():
            self._trip(HW_INPUT_VOLTAGE)

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

    @_locked
    def present_values(self) -> dict[str, int]:
        """Live register values as the servo would report them now."""
        self.advance()
        self._sync_live()
        return {r.name: r.decode(self.mem[r.address : r.end]) for r in self.table if 120 <= r.address < 148}

    def _sync_live(self) -> None:
        """Write the live (read-only) registers 120..146 from the physics state into memory (one pack)."""
        mem = self.mem
        if not self._live_dirty:
            _TICK.pack_into(mem, 120, int(self._t * 1000.0) % 32768)  # at rest only the clock moves
            return
        self._live_dirty = False
        motor = self.motor
        vel = motor.vel
        rev = mem[A_DRIVE] & 1
        offset = _I32.unpack_from(mem, 20)[0]
        prof_a, prof_v = _PROFILE.unpack_from(mem, 108)
        if rev:
            present = 4095.0 - motor.pos + offset
            target = 4095.0 - motor.target + offset
            load = -motor.load
            vel = -vel
        else:
            present = motor.pos + offset
            target = motor.target + offset
            load = motor.load
        moving = vel != 0.0
        status = (1 if abs(motor.target - motor.pos) <= IN_POSITION_TICK else 0) | (2 if moving else 0)
        if prof_v:
            status |= 0x30 if prof_a else 0x10
        present_load = load * (1000.0 if self._reports_load else self._stall_units)
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
            _LIVE.pack_into(
                mem, 120, *(_saturate(v, lo, hi) for v, (lo, hi) in zip(values, _LIVE_RANGES, strict=True))
            )


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


_LIMITS = struct.Struct("<III")  # Velocity Limit (44), Max (48) / Min (52) Position Limit
_GOALS = struct.Struct("<IIi")  # Profile Acceleration (108), Profile Velocity (112), Goal Position (116)


def _indirect_blocks(spec: ModelSpec) -> list[tuple[int, int, int]]:
    blocks: list[tuple[int, int, int]] = []
    for reg in spec.table:
        if not reg.name.startswith("Indirect Data "):
            continue
        n = int(reg.name.rsplit(" ", 1)[1])
        addr_reg = spec.table.get(f"Indirect Address {n}")
        if (
            blocks
            and blocks[-1][0] + blocks[-1][2] == reg.address
            and blocks[-1][1] + 2 * blocks[-1][2] == addr_reg.address
        ):
            d, a, c = blocks[-1]
            blocks[-1] = (d, a, c + 1)
        else:
            blocks.append((reg.address, addr_reg.address, 1))
    return blocks
