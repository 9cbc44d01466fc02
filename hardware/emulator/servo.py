"""One emulated servo: its control-table memory, the write rules behind the error byte, test hooks, power.

The physics (motion, heat, load, trips, live registers) lives in the base class
:class:`servoface.hardware.emulator.servo_motion.ServoMotion`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from functools import wraps
from typing import Any, TypeVar

from servoface.hardware.emulator.control_table import EEPROM_END, Register
from servoface.hardware.emulator.errors import EmulatorConfigError
from servoface.hardware.emulator.faults import FaultSchedule
from servoface.hardware.emulator.indirect import IndirectMap
from servoface.hardware.emulator.models import BAUD_CODES, HW_INPUT_VOLTAGE, TICKS_PER_REV, ModelSpec
from servoface.hardware.emulator.packet import ErrorNumber
from servoface.hardware.emulator.realism import Realism
from servoface.hardware.emulator.servo_motion import (
    A_DRIVE,
    A_GOAL_POS,
    A_HW_ERR,
    A_MODE,
    A_TORQUE,
    A_WATCHDOG,
    LIMITS,
    ServoMotion,
)

_F = TypeVar("_F", bound=Callable[..., Any])
A_FIRMWARE = 6
A_PROTOCOL = 13
A_STARTUP = 60
A_BACKUP_READY = 147
GAINS = slice(76, 92)  # the RAM a Control Table Backup keeps: velocity PI, position PID, feedforward gains
GOAL_ADDRESSES = (100, 102, 104, 116)  # Goal PWM, Current, Velocity, Position


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


class EmulatedServo(ServoMotion):
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
        realism: Realism | None = None,
    ) -> None:
        self.uid = uid
        self._lock = lock if lock is not None else threading.RLock()
        self.spec = spec
        self.table = spec.table
        self._clock = clock
        self._faults = faults
        self.registered: tuple[int, bytes] | None = None
        self.clamp_goals = False  # Goal Position beyond the limits: Data Limit Error (False) or clamp (True)
        self.silent_until_s = -math.inf
        self.on_change: Callable[[EmulatedServo], None] | None = None  # chain hook: id/baud/silence changed
        self.mem = bytearray()
        self.backup: bytes | None = None  # Control Table Backup (0x20): the image RAM Restore brings back
        # Firmware Version (6): the model's unless a test gives this servo another (``set_firmware``); it
        # decides whether Fast Sync / Bulk Read are answered (`FAST_READ_MIN_FIRMWARE`)
        self.firmware_version = spec.firmware_version
        self._init_motion(spec, clock, realism)
        self._indirect = IndirectMap(spec.table)
        self._indirect_lo = self._indirect.data_lo
        self._indirect_hi = self._indirect.data_hi
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
            return round(self._to_present(self.physical_tick))

    @property
    def shaft_tick(self) -> float:
        """Physical shaft angle in ticks (differs from Present Position by homing offset and reverse)."""
        with self._lock:
            self.advance()
            return self.physical_tick

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
    def set_firmware(self, version: int) -> None:
        """Test hook: this servo runs firmware ``version`` (Firmware Version, 6, reads it; below
        `FAST_READ_MIN_FIRMWARE` it does not answer Fast Sync / Bulk Read). Kept across reboots and resets."""
        if not 0 <= int(version) <= 255:
            raise EmulatorConfigError(f"firmware version {version}: expected 0..255")
        self.firmware_version = int(version)
        self.mem[A_FIRMWARE] = self.firmware_version

    @_locked
    def move_by_hand(self, present_tick: float) -> None:
        """Turn the horn by hand to where Present Position reads ``present_tick`` (only with torque off)."""
        self.advance()
        if self.torque_on:
            raise EmulatorConfigError(f"servo {self.id}: move_by_hand needs torque off (the motor holds its goal)")
        self.motor.pos = self.motor.target = self._to_shaft(float(present_tick))
        if self._real is not None:
            self._real.reset(self.motor.pos)
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
        image[A_FIRMWARE] = self.firmware_version
        self.mem = image
        self.registered = None
        self._watchdog_tripped = False
        self.motor.vel = 0.0
        self.motor.target = self.motor.pos
        self._plan_key = ()
        self.motor.overload_s = 0.0
        _put(self.mem, A_GOAL_POS, 4, round(self._to_present(self.motor.pos)))
        startup = self.mem[A_STARTUP] if A_STARTUP in self.table else 0
        if startup & 0x02 and self.backup is not None:  # RAM Restore: the backed-up gains
            self.mem[GAINS] = self.backup[GAINS]
        if A_BACKUP_READY in self.table:
            self.mem[A_BACKUP_READY] = 1 if self.backup is not None else 0
        self._recheck_causes()
        if startup & 0x01 and not self.mem[A_HW_ERR] & self.mem[63]:  # Startup Torque On
            self.mem[A_TORQUE] = 1
            self._start_move()
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

    @_locked
    def backup_control_table(self) -> None:
        """Control Table Backup (0x20, P1 = 0x01): keep EEPROM and the gains (for restore / RAM Restore)."""
        self.advance()
        self.backup = bytes(self.mem)
        if A_BACKUP_READY in self.table:
            self.mem[A_BACKUP_READY] = 1

    @_locked
    def restore_eeprom(self) -> None:
        """Control Table Backup, P1 = 0x02: EEPROM back from the backup area (the servo then reboots)."""
        self.advance()
        if self.backup is not None:
            self.mem[:EEPROM_END] = self.backup[:EEPROM_END]
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
        self._live_dirty = True  # Present Position (132) shows the cleared value at once

    # ----------------------------------------------------------------- reads
    def read_bytes(self, address: int, length: int) -> tuple[int, bytes]:
        """(error number, data) for a Read of ``length`` bytes at ``address``."""
        size = self.table.size
        if length < 0:
            return ErrorNumber.DATA_LENGTH, b""
        if address + length > size:
            # past the end of the table: Access Error ("an address that has not been defined"), with the
            # Read's data field still ``length`` bytes long (defined bytes, zeros past the end), so a
            # reader that ignores the error byte gets zeros instead of a short packet
            self.advance()
            if address < size:
                self._sync_live()
            head = bytes(self.mem[address:size]) if address < size else b""
            return ErrorNumber.ACCESS, head + bytes(length - len(head))
        t_s = self._clock()  # `advance()` inlined: one clock reading, no call when already there
        if t_s > self._t or self._real is not None:
            self.advance(t_s)
        end = address + length
        if address < 147 and end > 120:
            self._sync_live()
        if self._indirect_lo < end and address < self._indirect_hi:
            targets = self._indirect.targets(self.mem, address, length)
            if any(120 <= t < 147 for t in targets):
                self._sync_live()
            mem = self.mem
            size = len(mem)
            return 0, bytes(mem[t] if t < size else 0 for t in targets)
        return 0, bytes(self.mem[address:end])

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
        if a == A_PROTOCOL and value not in self.spec.protocol_types:
            return ErrorNumber.DATA_RANGE
        if a == A_GOAL_POS:
            if self._watchdog_tripped:
                return ErrorNumber.DATA_RANGE
            if mem[A_MODE] == 3:
                _, max_pos, min_pos = LIMITS.unpack_from(mem, 44)
                if not min_pos <= value <= max_pos and not self.clamp_goals:
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
        t_s = self._clock()  # `advance()` inlined: one clock reading, no call when already there
        if t_s > self._t or self._real is not None:
            self.advance(t_s)
        if self._indirect_lo < address + len(data) and address < self._indirect_hi:
            return self._write_indirect(address, data)
        err = self.check_write(address, data)
        if not err:
            self._apply(address, data)
        return err

    def _write_indirect(self, address: int, data: bytes) -> int:
        """A write touching Indirect Data goes to the mapped registers (all checked before any change)."""
        runs = self._indirect.runs(self.mem, address, data)
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
        if (
            mem[A_DRIVE] & 0x08
            and not mem[A_TORQUE]
            and any(address <= g < end for g in GOAL_ADDRESSES)
            and not mem[A_HW_ERR] & mem[63]
        ):
            mem[A_TORQUE] = 1  # Drive Mode bit 3, Torque On by Goal Update: the goal switches torque on
            self.motor.target = self.motor.pos
            self._plan_key = ()
        if mem[A_TORQUE] and ((address < 120 and end > 100) or (address < 56 and end > 44)):
            self._start_move()

    # ----------------------------------------------------------------- supply
    @_locked
    def set_input_voltage(self, volts: float) -> None:
        self.advance()
        self.input_voltage_v = float(volts)
        self._live_dirty = True
        if not self._voltage_ok():
            self._trip(HW_INPUT_VOLTAGE)

    @_locked
    def present_values(self) -> dict[str, int]:
        """Live register values as the servo would report them now."""
        self.advance()
        self._sync_live()
        return {r.name: r.decode(self.mem[r.address : r.end]) for r in self.table if 120 <= r.address < 148}
