"""The position sentinel: Present Position read through Indirect Data, with a witness byte that proves the
servo has not been reset since it was configured.

Four Indirect Address slots map Status Return Level (68) and Present Position's three low bytes (132..134)
to the four Indirect Data bytes at 224..227. While the map holds, the first byte is the servo's Status
Return Level (1 or 2: a servo that answers a read has one of those); the map lives in RAM, and a reset
(brown-out, power cycle, reboot) puts every Indirect Address back to its default (its own Indirect Data
byte, 0 after power-up), so the witness reads 0 and the driver knows in that very cycle. (The servo's ID,
7, would be the obvious witness, but Indirect Address accepts 64..661 only: EEPROM cannot be mapped.)

The witness first lets one map serve two read lengths:
- **3 bytes at 224** (`SENTINEL_SHORT`): witness + Present Position bits 0..15, signed. Enough for Position
  Control Mode (3), where Present Position stays within one turn (0..4095) plus Homing Offset: used when
  every servo of the chain is in that mode with a Homing Offset that keeps 0..4095 inside 16 bits (every
  face servo in practice). A byte per servo less than a read of Present Position (132, 4 bytes): 24 bytes
  of a 24-servo cycle's 532 at plain Sync Read (4.5 % of the wire), 24 of 372 with Fast Sync Read (6.5 %).
  (Only a shaft turned by hand more than 8 turns with torque off, off the head, could count past 16 bits
  and wrap; torque on re-pins the goal from a direct 4-byte read of Present Position, never from this one.)
- **4 bytes at 224** (`SENTINEL`): witness + bits 0..23, signed, which hold every Present Position of the
  other position modes (Extended / Current-based Position: +-256 turns), as many bytes as a direct read.
Which length the chain reads is decided from every servo's `SentinelMap.short`; other operating modes keep
the direct read.

One Sync Read reads one address from every servo, so the data sits at 224 on every servo, whatever its
table: the base control table has Indirect Data 1 at 224 (slots 1..4 feed 224..227); XL330 firmware >= 52
has 20 slots with data from 208, so its slots 17..20 feed 224..227. Which one a servo has is found by
read-back, never guessed from a model or firmware number: slots 1..4 are written, read back, and 224 read
between two direct reads of Present Position; if that does not verify, slots 17..20 the same way; else the
servo keeps the direct read and `SentinelMap.why` says why. So does a servo with RAM Restore on (Startup
Configuration bit 1): it may restore a backed-up RAM, the map included, at power-up, and then the witness
would not show the reset. No other slot is written (a user may use them),
and slots that were tried and do not feed 224 are written back as they were. Slots that already hold the map
(a re-configure with no reset since) are verified first, without a write.
"""

from __future__ import annotations

from dataclasses import dataclass

from servoface.hardware.bus import ServoBus
from servoface.hardware.errors import ServoStatusError
from servoface.hardware.registers import OperatingMode, Register

SLOT_TARGETS = (68, 132, 133, 134)  # the witness (Status Return Level), then Present Position bits 0..23
MAP_VALUE = int.from_bytes(b"".join(a.to_bytes(2, "little") for a in SLOT_TARGETS), "little")
SENTINEL = Register.INDIRECT_SENTINEL  # 224, 4 bytes, on every chain
SENTINEL_SHORT = Register.INDIRECT_SENTINEL_SHORT  # 224, 3 bytes: the witness and position bits 0..15
TICK_SIGN = {SENTINEL: 0x800000, SENTINEL_SHORT: 0x8000}  # per read: the sign bit of the position after >> 8
SLOTS = ((1, Register.INDIRECT_ADDRESS_1_4), (17, Register.INDIRECT_ADDRESS_17_20))  # tried in this order
POSITION_MODES = frozenset(
    {OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.CURRENT_BASED_POSITION}
)
ONE_TURN_TICK = 4096  # Position Control Mode keeps Present Position within 0..4095 (plus Homing Offset)
RAM_RESTORE_BIT = 0x02  # Startup Configuration (60) bit 1


@dataclass(frozen=True)
class SentinelMap:
    """What `map_sentinel` found for one servo."""

    slot: int | None  # the first Indirect Address slot of the verified map (1 or 17); None: direct reads
    witness: int  # the first byte while the map holds (the servo's Status Return Level); 0 without a map
    why: str  # how it was decided (for events and `Driver.sentinel_info`)
    short: bool = False  # every Present Position this servo can report fits 16 bits: 3-byte reads will do


def split(raw: int, register: Register = SENTINEL) -> tuple[int, int]:
    """(position tick, witness byte) of a sentinel read's value: the witness byte, then the position in
    two's complement (24 bits at `SENTINEL`, 16 at `SENTINEL_SHORT`)."""
    sign = TICK_SIGN[register]
    return ((raw >> 8) ^ sign) - sign, raw & 0xFF


def fits_short(operating_mode: int, homing_offset_tick: int) -> bool:
    """Every Present Position of a servo in ``operating_mode`` with ``homing_offset_tick`` fits 16 bits
    signed: Position Control Mode only (one turn, 0..4095, plus the offset); the other position modes
    count up to +-256 turns."""
    return operating_mode == OperatingMode.POSITION and -0x8000 <= homing_offset_tick <= 0x7FFF - (ONE_TURN_TICK - 1)


def map_sentinel(bus: ServoBus, servo_id: int, operating_mode: int) -> SentinelMap:
    """Write the sentinel's map to one servo (slots 1..4, else 17..20) until Indirect Data at 224 verifies;
    whether 3-byte reads will do (`fits_short`, from its Homing Offset as read).

    Call with torque off (configure): the position read at 224 is bracketed by two direct reads. A refusal
    by the servo (an error status) counts as not verified; bus failures raise.
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
        startup = bus.read(servo_id, Register.STARTUP_CONFIGURATION)
    except ServoStatusError:
        startup = 0  # no such register on this table (older firmware): nothing is restored at power-up
    if startup & RAM_RESTORE_BIT:
        return SentinelMap(
            None,
            0,
            f"servo {servo_id}: RAM Restore is on (Startup Configuration = {startup}, bit 1): a reset could "
            "restore a backed-up map, so the witness would not show it: direct reads",
        )
    witness = bus.read(servo_id, Register.STATUS_RETURN_LEVEL)
    short, reads = _short(bus, servo_id, mode)
    tried: list[str] = []
    was: dict[int, int] = {}
    for first, slots in SLOTS:
        try:
            was[first] = bus.read(servo_id, slots)
        except ServoStatusError as err:
            tried.append(f"slots {first}..{first + 3}: unreadable ({err})")
    # slots that hold the map already (configured before, no reset since) are checked first, unwritten: on
    # XL330, writing slots 1..4 while 17..20 still feed 224 would verify through 17..20 and keep 1..4 too
    for first, slots in sorted(SLOTS, key=lambda fs: was.get(fs[0]) != MAP_VALUE):
        if first not in was:
            continue
        name = f"slots {first}..{first + 3}"
        found = _try(bus, servo_id, slots, witness, write=was[first] != MAP_VALUE)
        if found is None:
            return SentinelMap(
                first,
                witness,
                f"servo {servo_id}: Indirect Data at {SENTINEL.address} verified ({name}; {reads})",
                short,
            )
        if was[first] != MAP_VALUE:
            try:  # these slots do not feed 224 on this servo: leave them as they were (a user may use them)
                bus.write(servo_id, slots, was[first])
            except ServoStatusError:
                pass
        if isinstance(found, SentinelMap):
            return found
        tried.append(f"{name}: {found}")
    return SentinelMap(
        None,
        0,
        f"servo {servo_id}: the sentinel did not verify at {SENTINEL.address} ({'; '.join(tried)}): direct reads",
    )


def _try(bus: ServoBus, servo_id: int, slots: Register, witness: int, *, write: bool) -> str | SentinelMap | None:
    """Map ``slots`` (``write``: else they hold the map already) and verify at 224: None when it verified, else
    why not (a `SentinelMap` when the servo cannot use the sentinel at all)."""
    if write:
        try:
            bus.write(servo_id, slots, MAP_VALUE)
        except ServoStatusError as err:
            return f"write refused ({err})"
    if bus.read(servo_id, slots) != MAP_VALUE:
        return "did not read back"
    before = bus.read(servo_id, Register.PRESENT_POSITION)
    if not -TICK_SIGN[SENTINEL] <= before < TICK_SIGN[SENTINEL]:
        return SentinelMap(None, 0, f"servo {servo_id}: Present Position {before} beyond 24 bits: direct reads")
    try:
        tick, byte = split(bus.read(servo_id, SENTINEL))
    except ServoStatusError as err:
        return f"{SENTINEL.address} unreadable ({err})"
    after = bus.read(servo_id, Register.PRESENT_POSITION)
    if witness and byte == witness and min(before, after) <= tick <= max(before, after):
        return None
    return f"read position {tick}, witness {byte} (expected {before}..{after}, {witness})"


def _short(bus: ServoBus, servo_id: int, mode: OperatingMode) -> tuple[bool, str]:
    """(3-byte reads will do, why) for a servo in a position ``mode``: its Homing Offset read (EEPROM) and
    `fits_short`. A servo that refuses the read keeps 4-byte reads."""
    if mode != OperatingMode.POSITION:
        return False, f"{mode.name} mode: 4-byte reads (position bits 0..23)"
    try:
        offset = bus.read(servo_id, Register.HOMING_OFFSET)
    except ServoStatusError as err:
        return False, f"Homing Offset unreadable ({err}): 4-byte reads"
    if not fits_short(mode, offset):
        return False, f"Homing Offset {offset}: positions beyond 16 bits, 4-byte reads"
    return True, "3-byte reads will do (position bits 0..15)"
