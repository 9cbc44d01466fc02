"""The position sentinel: Present Position read through Indirect Data, with a fourth byte that proves the
servo has not been reset since it was configured.

Indirect Address 1..4 map Present Position's three low bytes (132..134) and Status Return Level (68) to
Indirect Data 1..4, so the per-cycle position read is still 4 bytes (as a read of 132 is) and, while the
map holds, its fourth byte is the servo's Status Return Level (1 or 2: a servo that answers a read has
one of those). The map lives in RAM: a reset (brown-out, power cycle, reboot) puts every Indirect Address
back to its default (its own Indirect Data byte, 0 after power-up), so the fourth byte reads 0 and the
driver knows in that very cycle. (The servo's ID, 7, would be the obvious witness, but Indirect Address
accepts 64..661 only: EEPROM cannot be mapped.) 24 bits signed hold every Present Position of the position
modes (0..4095 plus Homing Offset, or +-256 turns); other operating modes keep the direct read.

Indirect Address 5..14 map the foldable telemetry after it (Moving 122, Present Current 126..127, Present
Velocity 128..131, Present Input Voltage 144..145, Present Temperature 146), so a due motion or thermal
group rides in the same read as a longer block (11 / 14 bytes instead of 14 / 15 from 122 / 132).

Where Indirect Data 1 sits differs (224 in the base control table, 208 in XL330 firmware >= 52): after the
map is written and read back, both places are read; the one that gives Status Return Level and the
position read directly around it is used. Neither (or both): the servo keeps the direct read, and
`SentinelMap.why` says why. Never guessed from a model or firmware number.
"""

from __future__ import annotations

from dataclasses import dataclass

from servoface.hardware.bus import ServoBus
from servoface.hardware.errors import ServoStatusError
from servoface.hardware.registers import OperatingMode, Register

SLOT_TARGETS = (132, 133, 134, 68, 122, 126, 127, 128, 129, 130, 131, 144, 145, 146)  # Indirect Address 1..14
MAP_VALUE = int.from_bytes(b"".join(a.to_bytes(2, "little") for a in SLOT_TARGETS), "little")
POSITION_MODES = frozenset(
    {OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.CURRENT_BASED_POSITION}
)
TICK_MASK = 0xFFFFFF
TICK_SIGN = 0x800000


@dataclass(frozen=True)
class SentinelView:
    """The mapped block at one Indirect Data address: the registers to read instead of the direct ones."""

    base: int  # address of Indirect Data 1
    sentinel: Register  # 4 bytes: position bits 0..23, then the witness byte
    motion: tuple[Register, ...]  # what folds in for the motion group (Moving, Current, Velocity)
    thermal: tuple[Register, ...]  # ... for the thermal group (Input Voltage, Temperature)
    direct: dict[Register, Register]  # each view register -> the register it stands for


def _view(base: int) -> SentinelView:
    """The view at ``base``, from the ``INDIRECT_<base>_*`` registers."""
    names = ("MOVING", "CURRENT", "VELOCITY", "VOLTAGE", "TEMPERATURE")
    regs = {name: Register[f"INDIRECT_{base}_{name}"] for name in names}
    return SentinelView(
        base,
        Register[f"INDIRECT_{base}_SENTINEL"],
        (regs["MOVING"], regs["CURRENT"], regs["VELOCITY"]),
        (regs["VOLTAGE"], regs["TEMPERATURE"]),
        {
            regs["MOVING"]: Register.MOVING,
            regs["CURRENT"]: Register.PRESENT_CURRENT,
            regs["VELOCITY"]: Register.PRESENT_VELOCITY,
            regs["VOLTAGE"]: Register.PRESENT_INPUT_VOLTAGE,
            regs["TEMPERATURE"]: Register.PRESENT_TEMPERATURE,
        },
    )


VIEWS: dict[int, SentinelView] = {base: _view(base) for base in (224, 208)}


@dataclass(frozen=True)
class SentinelMap:
    """What `map_sentinel` found for one servo."""

    base: int | None  # Indirect Data 1's address where the map verified; None: read Present Position directly
    witness: int  # the fourth byte while the map holds (the servo's Status Return Level); 0 without a map
    why: str  # how it was decided (for events and `Driver.sentinel_info`)


def split(raw: int) -> tuple[int, int]:
    """(position tick, witness byte) of a sentinel register's value (24-bit two's complement, then a byte)."""
    return ((raw & TICK_MASK) ^ TICK_SIGN) - TICK_SIGN, raw >> 24


def map_sentinel(bus: ServoBus, servo_id: int, operating_mode: int) -> SentinelMap:
    """Write the sentinel's map (Indirect Address 1..14) to one servo and find where its data reads back.

    Call with torque off (configure): the position read-back brackets the mapped one between two direct
    reads. A refusal by the servo (an error status) is a `SentinelMap` without a base; bus failures raise.
    """
    try:
        mode = OperatingMode(operating_mode)
    except ValueError:
        return SentinelMap(None, 0, f"servo {servo_id}: operating mode {operating_mode}: direct reads")
    if mode not in POSITION_MODES:
        return SentinelMap(
            None, 0, f"servo {servo_id}: {mode.name} mode (Present Position may exceed 24 bits): direct reads"
        )
    try:
        bus.write(servo_id, Register.INDIRECT_ADDRESS_1_14, MAP_VALUE)
    except ServoStatusError as err:
        return SentinelMap(None, 0, f"servo {servo_id}: Indirect Address write refused ({err}): direct reads")
    back = bus.read(servo_id, Register.INDIRECT_ADDRESS_1_14)
    if back != MAP_VALUE:
        return SentinelMap(None, 0, f"servo {servo_id}: Indirect Address 1..14 did not read back: direct reads")
    witness = bus.read(servo_id, Register.STATUS_RETURN_LEVEL)
    before = bus.read(servo_id, Register.PRESENT_POSITION)
    seen: dict[int, tuple[int, int]] = {}
    for base, view in VIEWS.items():
        try:
            seen[base] = split(bus.read(servo_id, view.sentinel))
        except ServoStatusError:
            continue  # no such address on this table (Access Error)
    after = bus.read(servo_id, Register.PRESENT_POSITION)
    lo, hi = min(before, after), max(before, after)
    if not -TICK_SIGN <= lo <= hi < TICK_SIGN:
        return SentinelMap(None, 0, f"servo {servo_id}: Present Position {before} beyond 24 bits: direct reads")
    found = [base for base, (tick, byte) in seen.items() if byte == witness and witness and lo <= tick <= hi]
    if len(found) != 1:
        got = ", ".join(f"@{b}: position {t}, witness {w}" for b, (t, w) in seen.items()) or "nothing"
        return SentinelMap(
            None,
            0,
            f"servo {servo_id}: the mapped data did not verify at exactly one of {sorted(VIEWS)} (read {got}; "
            f"expected position {before}..{after}, witness {witness}): direct reads",
        )
    return SentinelMap(found[0], witness, f"servo {servo_id}: Indirect Data 1 at {found[0]} verified")
