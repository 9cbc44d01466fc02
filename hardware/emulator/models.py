"""The four emulated models as data: control tables plus the physical figures the servo model needs.

Addresses are the X-series / MX(2.0) layout of the ROBOTIS e-manual (shared by all four; see
``/work/shared/reference/dynamixel.md`` §3). Defaults are the documented factory values.
"""

from __future__ import annotations

from dataclasses import dataclass

from servoface.hardware.emulator.control_table import RW, ControlTable, R, Register
from servoface.hardware.emulator.errors import EmulatorConfigError

# baud code (reg 8) -> bits per second
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
TICKS_PER_REV = 4096
VELOCITY_UNIT_RPM = 0.229
ACCELERATION_UNIT_RPM2 = 214.577

# Hardware Error Status (70) / Shutdown (63) bits
HW_INPUT_VOLTAGE = 0x01
HW_OVERHEATING = 0x04
HW_ENCODER = 0x08
HW_ELECTRICAL_SHOCK = 0x10
HW_OVERLOAD = 0x20

# Fast Sync Read (0x8A) / Fast Bulk Read (0x9A) came with a firmware update: older X-series firmware does not
# know the instruction and, as for any unknown broadcast instruction, stays silent. The threshold is the
# XL330's "v46+" (pollen-robotics/rustypot PR #122, "Add dynamixel fast sync read": "may need a firmware
# update (XL330: v46+)"); MX(2.0) firmware never answers it (ROBOTIS forum, "No response to fast sync read
# command with Dynamixel MX28-AR": "the DYNAMIXEL MX series (2.0 Firmware) does not function the Fast Sync /
# Bulk read / write instruction (DYNAMIXEL X Series only)"). The e-manual's own statement of the version
# was not in the reference corpus. Every stock model here ships at or above it (XL330 52, the others 46).
FAST_READ_MIN_FIRMWARE = 46


@dataclass(frozen=True)
class ModelSpec:
    """One servo model: its control table and the physics figures (SI units unless suffixed)."""

    name: str
    model_number: int
    firmware_version: int
    table: ControlTable
    operating_modes: frozenset[int]
    no_load_speed_rpm: float
    stall_torque_nm: float
    stall_current_a: float
    nominal_voltage_v: float
    # Present Current/Load (126): "current" in ``current_unit_ma`` per LSB, or "load" in 0.1 % of stall
    present_kind: str
    current_unit_ma: float
    max_baud_code: int
    # Protocol Type (13) values the page defines (XL330: 2, 20, 21, 22; the others: 1, 2)
    protocol_types: frozenset[int] = frozenset({1, 2})

    @property
    def no_load_speed_tick_s(self) -> float:
        return self.no_load_speed_rpm / 60.0 * TICKS_PER_REV


def _x_series_table(
    *,
    model_number: int,
    firmware: int,
    temperature_limit: int,
    max_voltage: int,
    min_voltage: int,
    voltage_range: tuple[int, int],
    velocity_limit: int,
    velocity_limit_max: int,
    shutdown: int,
    gains: tuple[int, int, int, int, int],
    current_limit: int | None,
    acceleration_limit: bool,
    max_baud_code: int,
    indirect: tuple[tuple[int, int, int], ...],
    extra: tuple[Register, ...] = (),
    present_name: str = "Present Current",
    drive_mode_max: int = 13,
    protocol_range: tuple[int, int] = (1, 2),
    indirect_max: int = 661,
    startup_configuration: bool = True,
) -> ControlTable:
    vi, vp, pd, pi, pp = gains
    v_lo, v_hi = voltage_range
    regs: list[Register] = [
        R("Model Number", 0, 2, model_number),
        R("Model Information", 2, 4),
        R("Firmware Version", 6, 1, firmware),
        RW("ID", 7, 1, 1, lo=0, hi=252),
        RW("Baud Rate", 8, 1, 1, unit="code", lo=0, hi=max_baud_code),
        RW("Return Delay Time", 9, 1, 250, unit="2 us", lo=0, hi=254),
        RW("Drive Mode", 10, 1, 0, unit="bits", lo=0, hi=drive_mode_max),
        RW("Operating Mode", 11, 1, 3, lo=0, hi=16),
        RW("Secondary(Shadow) ID", 12, 1, 255, lo=0, hi=255),
        RW("Protocol Type", 13, 1, 2, lo=protocol_range[0], hi=protocol_range[1]),
        RW("Homing Offset", 20, 4, 0, signed=True, unit="pulse", lo=-1_044_479, hi=1_044_479),
        RW("Moving Threshold", 24, 4, 10, unit="0.229 rpm", lo=0, hi=1023),
        RW("Temperature Limit", 31, 1, temperature_limit, unit="degC", lo=0, hi=100),
        RW("Max Voltage Limit", 32, 2, max_voltage, unit="0.1 V", lo=v_lo, hi=v_hi),
        RW("Min Voltage Limit", 34, 2, min_voltage, unit="0.1 V", lo=v_lo, hi=v_hi),
        RW("PWM Limit", 36, 2, 885, unit="0.113 %", lo=0, hi=885),
        RW("Velocity Limit", 44, 4, velocity_limit, unit="0.229 rpm", lo=0, hi=velocity_limit_max),
        RW("Max Position Limit", 48, 4, 4095, unit="pulse", lo=0, hi=4095),
        RW("Min Position Limit", 52, 4, 0, unit="pulse", lo=0, hi=4095),
        RW("Shutdown", 63, 1, shutdown, unit="bits", lo=0, hi=255),
        RW("Torque Enable", 64, 1, 0, lo=0, hi=1),
        RW("LED", 65, 1, 0, lo=0, hi=1),
        RW("Status Return Level", 68, 1, 2, lo=0, hi=2),
        R("Registered Instruction", 69, 1),
        R("Hardware Error Status", 70, 1, unit="bits"),
        RW("Velocity I Gain", 76, 2, vi, lo=0, hi=16383),
        RW("Velocity P Gain", 78, 2, vp, lo=0, hi=16383),
        RW("Position D Gain", 80, 2, pd, lo=0, hi=16383),
        RW("Position I Gain", 82, 2, pi, lo=0, hi=16383),
        RW("Position P Gain", 84, 2, pp, lo=0, hi=16383),
        RW("Feedforward 2nd Gain", 88, 2, 0, lo=0, hi=16383),
        RW("Feedforward 1st Gain", 90, 2, 0, lo=0, hi=16383),
        RW("Bus Watchdog", 98, 1, 0, signed=True, unit="20 ms", lo=0, hi=127),
        RW("Goal PWM", 100, 2, 885, signed=True, unit="0.113 %"),
        RW("Goal Velocity", 104, 4, 0, signed=True, unit="0.229 rpm"),
        RW("Profile Acceleration", 108, 4, 0, unit="214.577 rev/min^2 or ms", lo=0, hi=32767),
        RW("Profile Velocity", 112, 4, 0, unit="0.229 rpm or ms", lo=0, hi=32767),
        RW("Goal Position", 116, 4, 0, signed=True, unit="pulse", lo=-1_048_575, hi=1_048_575),
        R("Realtime Tick", 120, 2, unit="ms"),
        R("Moving", 122, 1),
        R("Moving Status", 123, 1, unit="bits"),
        R("Present PWM", 124, 2, signed=True, unit="0.113 %"),
        R(present_name, 126, 2, signed=True),
        R("Present Velocity", 128, 4, signed=True, unit="0.229 rpm"),
        R("Present Position", 132, 4, signed=True, unit="pulse"),
        R("Velocity Trajectory", 136, 4, signed=True, unit="0.229 rpm"),
        R("Position Trajectory", 140, 4, signed=True, unit="pulse"),
        R("Present Input Voltage", 144, 2, unit="0.1 V"),
        R("Present Temperature", 146, 1, unit="degC"),
        *extra,
    ]
    if startup_configuration:  # bit 0 Startup Torque On, bit 1 RAM Restore (firmware >= 45, XL330 >= 46)
        regs.append(RW("Startup Configuration", 60, 1, 0, unit="bits", lo=0, hi=3))
    if current_limit is not None:
        regs.append(RW("Current Limit", 38, 2, current_limit, lo=0, hi=current_limit))
        regs.append(RW("Goal Current", 102, 2, current_limit, signed=True))
    if acceleration_limit:
        regs.append(RW("Acceleration Limit", 40, 4, 32767, lo=0, hi=32767))
    for first, address_base, data_base in indirect:
        count = (data_base - address_base) // 2 if first == 1 and data_base - address_base <= 56 else 28
        for i in range(count):
            n = first + i
            regs.append(RW(f"Indirect Address {n}", address_base + 2 * i, 2, data_base + i, lo=64, hi=indirect_max))
            regs.append(RW(f"Indirect Data {n}", data_base + i, 1, 0, lo=0, hi=255))
    return ControlTable(regs)


XL330_M288 = ModelSpec(
    name="XL330-M288",
    model_number=1200,
    firmware_version=52,
    table=_x_series_table(
        model_number=1200,
        firmware=52,
        temperature_limit=70,
        max_voltage=70,
        min_voltage=35,
        voltage_range=(31, 70),
        velocity_limit=445,
        velocity_limit_max=2047,
        shutdown=53,
        gains=(1600, 180, 0, 0, 400),
        current_limit=1750,
        acceleration_limit=False,
        max_baud_code=6,
        indirect=((1, 168, 208),),  # 20 pairs: addresses 168..206, data 208..227 (firmware >= 52)
        extra=(RW("PWM Slope", 62, 1, 140, lo=1, hi=255), R("Backup Ready", 147, 1)),
        protocol_range=(2, 22),  # only 2, 20, 21, 22 are defined: see protocol_types
        indirect_max=227,  # the last Indirect Data byte of this table
    ),
    operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
    no_load_speed_rpm=103.0,
    stall_torque_nm=0.52,
    stall_current_a=1.47,
    nominal_voltage_v=5.0,
    present_kind="current",
    current_unit_ma=1.0,
    max_baud_code=6,
    protocol_types=frozenset({2, 20, 21, 22}),
)

XL430_W250 = ModelSpec(
    name="XL430-W250",
    model_number=1060,
    firmware_version=46,
    table=_x_series_table(
        model_number=1060,
        firmware=46,
        temperature_limit=72,
        max_voltage=140,
        min_voltage=60,
        voltage_range=(60, 140),
        velocity_limit=265,
        velocity_limit_max=1023,
        shutdown=52,
        gains=(1000, 100, 4000, 0, 640),
        current_limit=None,
        acceleration_limit=False,
        max_baud_code=7,
        indirect=((1, 168, 224), (29, 578, 634)),
        extra=(R("Backup Ready", 147, 1),),
        present_name="Present Load",
    ),
    operating_modes=frozenset({1, 3, 4, 16}),
    no_load_speed_rpm=57.0,
    stall_torque_nm=1.4,
    stall_current_a=1.4,
    nominal_voltage_v=11.1,
    present_kind="load",
    current_unit_ma=1.0,
    max_baud_code=7,
)

XM430_W350 = ModelSpec(
    name="XM430-W350",
    model_number=1020,
    firmware_version=46,
    table=_x_series_table(
        model_number=1020,
        firmware=46,
        temperature_limit=80,
        max_voltage=160,
        min_voltage=95,
        voltage_range=(95, 160),
        velocity_limit=200,
        velocity_limit_max=1023,
        shutdown=52,
        gains=(1920, 100, 0, 0, 800),
        current_limit=1193,
        acceleration_limit=False,
        max_baud_code=7,
        indirect=((1, 168, 224), (29, 578, 634)),
        extra=(R("Backup Ready", 147, 1),),
    ),
    operating_modes=frozenset({0, 1, 3, 4, 5, 16}),
    no_load_speed_rpm=46.0,
    stall_torque_nm=4.1,
    stall_current_a=2.3,
    nominal_voltage_v=12.0,
    present_kind="current",
    current_unit_ma=2.69,
    max_baud_code=7,
)

MX28_2 = ModelSpec(
    name="MX-28(2.0)",
    model_number=30,
    firmware_version=46,
    table=_x_series_table(
        model_number=30,
        firmware=46,
        temperature_limit=80,
        max_voltage=160,
        min_voltage=95,
        voltage_range=(95, 160),
        velocity_limit=230,
        velocity_limit_max=1023,
        shutdown=52,
        gains=(1920, 100, 0, 0, 850),
        current_limit=None,
        acceleration_limit=True,
        max_baud_code=7,
        indirect=((1, 168, 224), (29, 578, 634)),
        present_name="Present Load",
        drive_mode_max=5,  # bits 0 (reverse) and 2 (time-based profile); no Torque On by Goal Update
        startup_configuration=False,  # not on the MX-28(2.0) page
    ),
    operating_modes=frozenset({1, 3, 4, 16}),
    no_load_speed_rpm=55.0,
    stall_torque_nm=2.5,
    stall_current_a=1.4,
    nominal_voltage_v=12.0,
    present_kind="load",
    current_unit_ma=1.0,
    max_baud_code=7,
)

MODELS: dict[str, ModelSpec] = {m.name: m for m in (XL330_M288, XL430_W250, XM430_W350, MX28_2)}
_ALIASES = {"MX-28": "MX-28(2.0)", "MX28": "MX-28(2.0)", "MX-28(2)": "MX-28(2.0)", "MX-28-2.0": "MX-28(2.0)"}


def get_model(name: str | ModelSpec) -> ModelSpec:
    """The model called ``name`` (any case): "XL330-M288", "XL430-W250", "XM430-W350", "MX-28(2.0)"."""
    if isinstance(name, ModelSpec):
        return name
    upper = name.strip().upper()
    upper = _ALIASES.get(upper, upper)
    for key, spec in MODELS.items():
        if key.upper() == upper or key.upper().replace("-", "") == upper.replace("-", ""):
            return spec
    raise EmulatorConfigError(f"unknown servo model {name!r}: expected one of {sorted(MODELS)}")


def baud_code_for(baud: int, spec: ModelSpec) -> int:
    """Baud Rate register code for ``baud`` bps on ``spec``."""
    for code, bps in BAUD_CODES.items():
        if bps == baud and code <= spec.max_baud_code:
            return code
    allowed = [bps for code, bps in BAUD_CODES.items() if code <= spec.max_baud_code]
    raise EmulatorConfigError(f"baud {baud} is not a {spec.name} baud rate: expected one of {allowed}")
