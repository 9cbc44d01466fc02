"""Protocol 2.0 control table of X-series / MX(2.0) servos: registers as an enum (address, size, sign, area).

The driver's own transcription of the ROBOTIS e-manual (XL330-M288, XL430-W250, XM430-W350, MX-28(2.0));
the emulator keeps an independent one, so a wrong address here cannot pass its own test.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum, IntFlag


class Area(Enum):
    """Where a register lives: EEPROM (writable only with torque off), RAM, or read-only."""

    EEPROM = "eeprom"
    RAM = "ram"
    READ_ONLY = "read-only"


class Register(Enum):
    """A control-table field: ``(address, size in bytes, signed, area)``; same on all supported models."""

    MODEL_NUMBER = (0, 2, False, Area.READ_ONLY)
    MODEL_INFORMATION = (2, 4, False, Area.READ_ONLY)
    FIRMWARE_VERSION = (6, 1, False, Area.READ_ONLY)
    ID = (7, 1, False, Area.EEPROM)
    BAUD_RATE = (8, 1, False, Area.EEPROM)
    RETURN_DELAY_TIME = (9, 1, False, Area.EEPROM)  # 2 us units
    DRIVE_MODE = (10, 1, False, Area.EEPROM)
    OPERATING_MODE = (11, 1, False, Area.EEPROM)
    SECONDARY_ID = (12, 1, False, Area.EEPROM)
    PROTOCOL_TYPE = (13, 1, False, Area.EEPROM)
    HOMING_OFFSET = (20, 4, True, Area.EEPROM)
    MOVING_THRESHOLD = (24, 4, False, Area.EEPROM)
    TEMPERATURE_LIMIT = (31, 1, False, Area.EEPROM)  # deg C
    MAX_VOLTAGE_LIMIT = (32, 2, False, Area.EEPROM)  # 0.1 V
    MIN_VOLTAGE_LIMIT = (34, 2, False, Area.EEPROM)  # 0.1 V
    PWM_LIMIT = (36, 2, False, Area.EEPROM)
    CURRENT_LIMIT = (38, 2, False, Area.EEPROM)
    VELOCITY_LIMIT = (44, 4, False, Area.EEPROM)
    MAX_POSITION_LIMIT = (48, 4, False, Area.EEPROM)
    MIN_POSITION_LIMIT = (52, 4, False, Area.EEPROM)
    SHUTDOWN = (63, 1, False, Area.EEPROM)
    TORQUE_ENABLE = (64, 1, False, Area.RAM)
    LED = (65, 1, False, Area.RAM)
    STATUS_RETURN_LEVEL = (68, 1, False, Area.RAM)
    REGISTERED_INSTRUCTION = (69, 1, False, Area.READ_ONLY)
    HARDWARE_ERROR_STATUS = (70, 1, False, Area.READ_ONLY)
    VELOCITY_I_GAIN = (76, 2, False, Area.RAM)
    VELOCITY_P_GAIN = (78, 2, False, Area.RAM)
    POSITION_D_GAIN = (80, 2, False, Area.RAM)
    POSITION_I_GAIN = (82, 2, False, Area.RAM)
    POSITION_P_GAIN = (84, 2, False, Area.RAM)
    BUS_WATCHDOG = (98, 1, True, Area.RAM)  # 20 ms units; reads -1 once tripped
    GOAL_PWM = (100, 2, True, Area.RAM)
    GOAL_CURRENT = (102, 2, True, Area.RAM)
    GOAL_VELOCITY = (104, 4, True, Area.RAM)
    PROFILE_ACCELERATION = (108, 4, False, Area.RAM)
    PROFILE_VELOCITY = (112, 4, False, Area.RAM)
    GOAL_POSITION = (116, 4, True, Area.RAM)
    REALTIME_TICK = (120, 2, False, Area.READ_ONLY)
    MOVING = (122, 1, False, Area.READ_ONLY)
    MOVING_STATUS = (123, 1, False, Area.READ_ONLY)
    PRESENT_PWM = (124, 2, True, Area.READ_ONLY)
    PRESENT_CURRENT = (126, 2, True, Area.READ_ONLY)  # current on XL330/XM430, load (0.1 %) on XL430/MX-28
    PRESENT_VELOCITY = (128, 4, True, Area.READ_ONLY)  # 0.229 rpm
    PRESENT_POSITION = (132, 4, True, Area.READ_ONLY)
    VELOCITY_TRAJECTORY = (136, 4, True, Area.READ_ONLY)
    POSITION_TRAJECTORY = (140, 4, True, Area.READ_ONLY)
    PRESENT_INPUT_VOLTAGE = (144, 2, False, Area.READ_ONLY)  # 0.1 V
    PRESENT_TEMPERATURE = (146, 1, False, Area.READ_ONLY)  # deg C
    # bit 0 Startup Torque On, bit 1 RAM Restore (firmware >= 45; XL330 >= 46); absent on MX-28(2.0)
    STARTUP_CONFIGURATION = (60, 1, False, Area.EEPROM)
    # The position sentinel (hardware/sentinel.py). Indirect Address slots, 2 bytes each, little-endian,
    # from 168 on every model: slots 1..4 (168..175) feed Indirect Data 1..4 at 224 in the base control
    # table; on XL330 firmware >= 52 (20 slots, data from 208) slots 17..20 (200..207) feed 224..227.
    INDIRECT_ADDRESS_1_4 = (168, 8, False, Area.RAM)
    INDIRECT_ADDRESS_17_20 = (200, 8, False, Area.RAM)
    # Indirect Data at 224..227 on every chain: the witness byte, then Present Position bits 0..23; the
    # short read stops after bits 0..15 (Position Control Mode: one turn plus Homing Offset fits 16 bits)
    INDIRECT_SENTINEL = (224, 4, False, Area.RAM)
    INDIRECT_SENTINEL_SHORT = (224, 3, False, Area.RAM)

    def __init__(self, address: int, size: int, signed: bool, area: Area) -> None:
        self.address = address
        self.size = size
        self.signed = signed
        self.area = area

    # members are singletons compared by identity: hash them by identity too (C speed; Enum's own __hash__
    # is a Python call on the name, and registers key the per-servo dicts of every read, every cycle)
    __hash__ = object.__hash__

    def __repr__(self) -> str:
        return f"<Register.{self.name} @{self.address}/{self.size}{'s' if self.signed else ''}>"

    @property
    def end(self) -> int:
        """First address after this field."""
        return self.address + self.size

    def encode(self, value: int) -> bytes:
        """Little-endian bytes of ``value``; raises ValueError if it does not fit the field."""
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{self.name}: expected an int, got {value!r}")
        lo, hi = self.value_range
        if not lo <= value <= hi:
            raise ValueError(f"{self.name}: {value} does not fit {self.size} byte(s) ({lo}..{hi})")
        return value.to_bytes(self.size, "little", signed=self.signed)

    def decode(self, data: bytes | bytearray | list[int] | int) -> int:
        """Value of the field from its little-endian bytes (or from the SDK's unsigned int), sign applied."""
        if isinstance(data, int):
            raw = data & ((1 << (8 * self.size)) - 1)
            data = raw.to_bytes(self.size, "little")
        return int.from_bytes(bytes(data[: self.size]), "little", signed=self.signed)

    @property
    def value_range(self) -> tuple[int, int]:
        bits = 8 * self.size
        if self.signed:
            return -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        return 0, (1 << bits) - 1


def span(registers: list[Register] | tuple[Register, ...]) -> tuple[int, int]:
    """``(start address, length)`` of the contiguous block covering ``registers`` (gaps are read too)."""
    if not registers:
        raise ValueError("span of no registers")
    start = min(r.address for r in registers)
    return start, max(r.end for r in registers) - start


def slice_value(register: Register, start: int, block: bytes | bytearray | list[int]) -> int:
    """Decode ``register`` from a block of bytes that begins at address ``start``."""
    offset = register.address - start
    return register.decode(bytes(block[offset : offset + register.size]))


class HardwareErrorBits(IntFlag):
    """Hardware Error Status (70) and Shutdown (63) bits, X-series and MX(2.0)."""

    NONE = 0
    INPUT_VOLTAGE = 0x01
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20


class OperatingMode(IntEnum):
    CURRENT = 0
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5
    PWM = 16


DRIVE_MODE_REVERSE = 0x01
DRIVE_MODE_TIME_BASED_PROFILE = 0x04

STATUS_ALERT_BIT = 0x80
STATUS_ERROR_NAMES: dict[int, str] = {
    1: "Result Fail",
    2: "Instruction Error",
    3: "CRC Error",
    4: "Data Range Error",
    5: "Data Length Error",
    6: "Data Limit Error",
    7: "Access Error",
}

BAUD_CODES: dict[int, int] = {
    0: 9_600,
    1: 57_600,
    2: 115_200,
    3: 1_000_000,
    4: 2_000_000,
    5: 3_000_000,
    6: 4_000_000,
    7: 4_500_000,
}

VELOCITY_RPM_PER_LSB = 0.229
TICKS_PER_REV = 4096


@dataclass(frozen=True)
class ModelInfo:
    """What the driver needs to know about a servo model (e-manual figures)."""

    number: int
    name: str
    reports_current: bool  # Present Current (True) or Present Load in 0.1 % (False) at address 126
    current_ma_per_lsb: float  # 0 when the model reports load
    default_shutdown: HardwareErrorBits
    default_temperature_limit_c: int
    supply_min_v: float  # recommended supply range
    supply_max_v: float
    operating_modes: frozenset[OperatingMode]
    max_baud: int


_ALL_MODES = frozenset(OperatingMode)
_NO_CURRENT = frozenset(
    {OperatingMode.VELOCITY, OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.PWM}
)
_DEFAULT_SHUTDOWN = HardwareErrorBits.OVERHEATING | HardwareErrorBits.ELECTRICAL_SHOCK | HardwareErrorBits.OVERLOAD

MODELS: dict[int, ModelInfo] = {
    m.number: m
    for m in (
        ModelInfo(
            1200,
            "XL330-M288",
            True,
            1.0,
            _DEFAULT_SHUTDOWN | HardwareErrorBits.INPUT_VOLTAGE,
            70,
            3.7,
            6.0,
            _ALL_MODES,
            4_000_000,
        ),
        ModelInfo(1060, "XL430-W250", False, 0.0, _DEFAULT_SHUTDOWN, 72, 6.5, 12.0, _NO_CURRENT, 4_500_000),
        ModelInfo(1020, "XM430-W350", True, 2.69, _DEFAULT_SHUTDOWN, 80, 10.0, 14.8, _ALL_MODES, 4_500_000),
        ModelInfo(1030, "XM430-W210", True, 2.69, _DEFAULT_SHUTDOWN, 80, 10.0, 14.8, _ALL_MODES, 4_500_000),
        ModelInfo(30, "MX-28(2.0)", False, 0.0, _DEFAULT_SHUTDOWN, 80, 10.0, 14.8, _NO_CURRENT, 4_500_000),
    )
}
MODELS_BY_NAME: dict[str, ModelInfo] = {m.name: m for m in MODELS.values()}


def model_by_name(name: str) -> ModelInfo:
    """Look a model up by its name (``"XL330-M288"``; a trailing ``-T``/``-R`` variant suffix is accepted)."""
    key = name.strip().upper()
    for suffix in ("-T", "-R"):
        if key.endswith(suffix) and key[: -len(suffix)] in MODELS_BY_NAME:
            key = key[: -len(suffix)]
    if key not in MODELS_BY_NAME:
        raise KeyError(f"unknown servo model {name!r}; known: {sorted(MODELS_BY_NAME)}")
    return MODELS_BY_NAME[key]


def model_name(number: int) -> str:
    """Name of a model number, or ``"unknown (N)"``."""
    info = MODELS.get(number)
    return info.name if info else f"unknown ({number})"
