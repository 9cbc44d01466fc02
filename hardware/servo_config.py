"""Servo descriptions and configuring a chain from them.

A `ServoSpec` says what one servo must be (id, model, role, position limits, profile, return delay, modes,
shutdown mask, temperature and voltage limits). `configure_servo` writes it: EEPROM fields only with torque
off and only where they differ (EEPROM wears), RAM fields after the operating mode (changing the mode
resets the profile), then reads everything back and raises `ServoConfigMismatch` naming servo and field.
The Min/Max Position Limit registers are the hardware backstop behind the driver's own goal check.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from servoface.hardware.bus import ServoBus
from servoface.hardware.errors import ServoConfigMismatch, ServoDescriptionError, ServoModelMismatch
from servoface.hardware.registers import (
    DRIVE_MODE_TIME_BASED_PROFILE,
    HardwareErrorBits,
    ModelInfo,
    OperatingMode,
    Register,
    model_by_name,
    model_name,
)
from servoface.hardware.sentinel import SentinelMap, map_sentinel

POSITION_RANGE_TICK = (0, 4095)
EXTENDED_RANGE_TICK = (-1_048_575, 1_048_575)


@dataclass(frozen=True)
class ServoSpec:
    """One servo as the head needs it. Register units unless a suffix says otherwise."""

    servo_id: int
    model: str
    role: str = ""
    min_position_tick: int = 0
    max_position_tick: int = 4095
    profile_velocity: int = 0  # 0.229 rpm (velocity-based) or ms (time-based); 0 = unlimited
    profile_acceleration: int = 0
    return_delay_us: int = 0  # Return Delay Time in us (2 us steps, 0..508); the factory 500 us slows reads
    operating_mode: OperatingMode = OperatingMode.POSITION
    drive_mode: int = 0
    shutdown: HardwareErrorBits | None = None  # None: the model's default mask
    temperature_limit_c: int | None = None  # None: leave the servo's value
    min_voltage_v: float | None = None
    max_voltage_v: float | None = None
    current_limit: int | None = None
    moving_threshold: int | None = None
    extra_ram: Mapping[Register, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.validate()

    @property
    def label(self) -> str:
        return f"servo {self.servo_id}" + (f" ({self.role})" if self.role else "")

    def _fail(self, name: str, what: str) -> ServoDescriptionError:
        return ServoDescriptionError(self.servo_id, name, f"{self.label}: {name} {what}")

    @property
    def model_info(self) -> ModelInfo:
        return model_by_name(self.model)

    def validate(self) -> None:
        sid = self.servo_id
        if isinstance(sid, bool) or not isinstance(sid, int) or not 0 <= sid <= 252:
            raise ServoDescriptionError(None, "servo_id", f"servo_id {sid!r} ({self.role}): expected an int 0..252")
        try:
            info = model_by_name(self.model)
        except KeyError as err:
            raise self._fail("model", f"{self.model!r} is unknown ({err.args[0]})") from err
        ints = (
            "min_position_tick",
            "max_position_tick",
            "profile_velocity",
            "profile_acceleration",
            "return_delay_us",
            "drive_mode",
        )
        for name in ints:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise self._fail(name, f"= {value!r}: expected an int")
        try:
            mode = OperatingMode(self.operating_mode)
        except ValueError as err:
            raise self._fail(
                "operating_mode",
                f"= {self.operating_mode!r}: expected one of {[int(m) for m in OperatingMode]}",
            ) from err
        if mode not in info.operating_modes:
            raise self._fail("operating_mode", f"= {mode.name} is not supported by {info.name}")
        lo, hi = (
            EXTENDED_RANGE_TICK
            if mode in (OperatingMode.EXTENDED_POSITION, OperatingMode.CURRENT_BASED_POSITION)
            else POSITION_RANGE_TICK
        )
        if not lo <= self.min_position_tick <= self.max_position_tick <= hi:
            raise self._fail(
                "min_position_tick/max_position_tick",
                f"= {self.min_position_tick}..{self.max_position_tick}: expected {lo} <= min <= max <= {hi}",
            )
        for name in ("profile_velocity", "profile_acceleration"):
            if not 0 <= getattr(self, name) <= 32767:
                raise self._fail(name, f"= {getattr(self, name)}: expected 0..32767")
        if self.drive_mode & DRIVE_MODE_TIME_BASED_PROFILE and self.profile_acceleration > self.profile_velocity // 2:
            raise self._fail(
                "profile_acceleration",
                f"= {self.profile_acceleration} ms: time-based profile needs "
                f"acceleration <= profile_velocity / 2 = {self.profile_velocity // 2}",
            )
        if not 0 <= self.return_delay_us <= 508 or self.return_delay_us % 2:
            raise self._fail("return_delay_us", f"= {self.return_delay_us}: expected an even number 0..508")
        if not 0 <= self.drive_mode <= 0x0D:
            raise self._fail("drive_mode", f"= {self.drive_mode}: expected bits 0 (reverse), 2 (time-based), 3")
        if self.shutdown is not None and (int(self.shutdown) & ~0x3D or int(self.shutdown) < 0):
            raise self._fail("shutdown", f"= {self.shutdown!r}: expected HardwareErrorBits (0x01|0x04|0x08|0x10|0x20)")
        if self.temperature_limit_c is not None and not (
            isinstance(self.temperature_limit_c, int) and 0 <= self.temperature_limit_c <= 100
        ):
            raise self._fail("temperature_limit_c", f"= {self.temperature_limit_c!r}: expected an int 0..100")
        for name in ("min_voltage_v", "max_voltage_v"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, int | float) and math.isfinite(value) and 0 < value < 30):
                raise self._fail(name, f"= {value!r}: expected volts, 0 < V < 30")
        if (
            self.min_voltage_v is not None
            and self.max_voltage_v is not None
            and self.min_voltage_v >= self.max_voltage_v
        ):
            raise self._fail(
                "min_voltage_v", f"= {self.min_voltage_v} must be below max_voltage_v = {self.max_voltage_v}"
            )
        if self.current_limit is not None:
            if not info.reports_current:
                raise self._fail("current_limit", f"is not available on {info.name}")
            if (
                isinstance(self.current_limit, bool)
                or not isinstance(self.current_limit, int)
                or not (0 <= self.current_limit <= 2047)
            ):
                raise self._fail("current_limit", f"= {self.current_limit!r}: expected an int 0..2047")
        for reg, value in self.extra_ram.items():
            if not isinstance(reg, Register) or reg.area.name != "RAM":
                raise self._fail("extra_ram", f"key {reg!r}: expected a RAM Register")
            try:
                reg.encode(value)
            except ValueError as err:
                raise self._fail(f"extra_ram[{reg.name}]", str(err)) from err

    # -- register values -------------------------------------------------------------------------------
    def eeprom_values(self) -> dict[Register, int]:
        """EEPROM registers this spec sets, in write order."""
        out: dict[Register, int] = {
            Register.OPERATING_MODE: int(self.operating_mode),
            Register.DRIVE_MODE: self.drive_mode,
            Register.RETURN_DELAY_TIME: self.return_delay_us // 2,
            Register.SHUTDOWN: int(self.shutdown if self.shutdown is not None else self.model_info.default_shutdown),
        }
        if self.operating_mode == OperatingMode.POSITION:  # the servo ignores the limits in other modes
            out[Register.MIN_POSITION_LIMIT] = self.min_position_tick
            out[Register.MAX_POSITION_LIMIT] = self.max_position_tick
        if self.temperature_limit_c is not None:
            out[Register.TEMPERATURE_LIMIT] = self.temperature_limit_c
        if self.min_voltage_v is not None:
            out[Register.MIN_VOLTAGE_LIMIT] = round(self.min_voltage_v * 10)
        if self.max_voltage_v is not None:
            out[Register.MAX_VOLTAGE_LIMIT] = round(self.max_voltage_v * 10)
        if self.current_limit is not None:
            out[Register.CURRENT_LIMIT] = self.current_limit
        if self.moving_threshold is not None:
            out[Register.MOVING_THRESHOLD] = self.moving_threshold
        return out

    def ram_values(self) -> dict[Register, int]:
        """RAM registers this spec sets (written after the operating mode, which resets the profile)."""
        out = {
            Register.PROFILE_ACCELERATION: self.profile_acceleration,
            Register.PROFILE_VELOCITY: self.profile_velocity,
        }
        out.update(self.extra_ram)
        return out

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], key_path: str = "servo") -> ServoSpec:
        """Build from a TOML/JSON table; errors name ``key_path`` and the field."""
        known = {f for f in cls.__dataclass_fields__ if f != "extra_ram"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ServoDescriptionError(
                data.get("servo_id") if isinstance(data.get("servo_id"), int) else None,
                unknown[0],
                f"{key_path}: unknown field(s) {unknown}; expected some of {sorted(known)}",
            )
        for required in ("servo_id", "model"):
            if required not in data:
                raise ServoDescriptionError(None, required, f"{key_path}: missing required field {required!r}")
        kwargs = dict(data)
        if "operating_mode" in kwargs and isinstance(kwargs["operating_mode"], str):
            try:
                kwargs["operating_mode"] = OperatingMode[kwargs["operating_mode"].upper()]
            except KeyError as err:
                raise ServoDescriptionError(
                    data["servo_id"],
                    "operating_mode",
                    f"{key_path}.operating_mode: unknown mode {data['operating_mode']!r}",
                ) from err
        if "shutdown" in kwargs and isinstance(kwargs["shutdown"], int) and not isinstance(kwargs["shutdown"], bool):
            kwargs["shutdown"] = HardwareErrorBits(kwargs["shutdown"])
        try:
            return cls(**kwargs)
        except ServoDescriptionError as err:
            raise ServoDescriptionError(err.servo_id, err.field, f"{key_path}: {err}") from err


def check_specs(specs: Iterable[ServoSpec]) -> list[ServoSpec]:
    """All specs valid and ids unique (roles too, when given)."""
    out = list(specs)
    seen: dict[int, ServoSpec] = {}
    roles: dict[str, int] = {}
    for spec in out:
        if spec.servo_id in seen:
            raise ServoDescriptionError(spec.servo_id, "servo_id", f"{spec.label}: id used twice")
        seen[spec.servo_id] = spec
        if spec.role:
            if spec.role in roles:
                raise ServoDescriptionError(
                    spec.servo_id,
                    "role",
                    f"{spec.label}: role {spec.role!r} already used by servo {roles[spec.role]}",
                )
            roles[spec.role] = spec.servo_id
    return out


@dataclass(frozen=True)
class ConfigReport:
    """What `configure_servo` did to one servo."""

    servo_id: int
    model_number: int
    firmware_version: int
    written: tuple[str, ...]  # register names written (EEPROM only when they differed)
    limits: Mapping[Register, int]  # limits read back (temperature, voltage, current, position)
    sentinel: SentinelMap | None = None  # the position sentinel's map (hardware/sentinel.py); None: not asked


_READBACK = (
    Register.TEMPERATURE_LIMIT,
    Register.MAX_VOLTAGE_LIMIT,
    Register.MIN_VOLTAGE_LIMIT,
    Register.CURRENT_LIMIT,
    Register.MAX_POSITION_LIMIT,
    Register.MIN_POSITION_LIMIT,
)


def configure_servo(bus: ServoBus, spec: ServoSpec, *, position_sentinel: bool = False) -> ConfigReport:
    """Write ``spec`` to its servo and verify by reading back. Leaves torque OFF (the driver pins goals).
    ``position_sentinel``: also map and verify the position sentinel (`map_sentinel`; the driver's reads use
    it); without it no Indirect Address is written.

    Raises `ServoConfigMismatch` (wrong model, or a value that does not read back) and the bus errors.
    """
    reply = bus.ping(spec.servo_id)
    expected_model = spec.model_info.number
    if reply.model_number != expected_model:
        raise ServoModelMismatch(
            spec.servo_id, expected_model, reply.model_number, spec.model_info.name, model_name(reply.model_number)
        )
    if bus.read(spec.servo_id, Register.TORQUE_ENABLE):
        bus.write(spec.servo_id, Register.TORQUE_ENABLE, 0)
    written: list[str] = []
    eeprom = spec.eeprom_values()
    present = bus.read_many(spec.servo_id, sorted(eeprom, key=lambda r: r.address))
    for reg, value in eeprom.items():
        if present[reg] != value:
            bus.write(spec.servo_id, reg, value)
            written.append(reg.name)
    for reg, value in spec.ram_values().items():
        bus.write(spec.servo_id, reg, value)
        written.append(reg.name)
    wanted = {**eeprom, **spec.ram_values()}
    back = bus.read_many(spec.servo_id, sorted(set(wanted) | set(_READBACK), key=lambda r: r.address))
    for reg, value in wanted.items():
        if back[reg] != value:
            raise ServoConfigMismatch(spec.servo_id, reg.name, value, back[reg])
    sentinel = map_sentinel(bus, spec.servo_id, spec.operating_mode) if position_sentinel else None  # RAM
    return ConfigReport(
        spec.servo_id,
        reply.model_number,
        reply.firmware_version,
        tuple(written),
        {r: back[r] for r in _READBACK},
        sentinel,
    )


def configure_chain(bus: ServoBus, specs: Sequence[ServoSpec]) -> dict[int, ConfigReport]:
    """Validate every spec first (nothing sent on a bad one), then configure servo by servo."""
    checked = check_specs(specs)
    return {spec.servo_id: configure_servo(bus, spec) for spec in checked}


def describe_model(number: int) -> str:
    return model_name(number)
