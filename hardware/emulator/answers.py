"""Who answers an instruction and how: Status Return Level, the error byte with its Alert bit, and the
replies (in wire order) an instruction produces."""

from __future__ import annotations

from dataclasses import dataclass

from servoface.hardware.emulator.packet import ALERT_BIT, Instruction, build_status
from servoface.hardware.emulator.servo import EmulatedServo

LEVEL_PING_ONLY, LEVEL_READ = 0, 1
READS = (
    Instruction.READ,
    Instruction.SYNC_READ,
    Instruction.BULK_READ,
    Instruction.FAST_SYNC_READ,
    Instruction.FAST_BULK_READ,
)


@dataclass(slots=True)
class Reply:
    """Bytes one servo puts on the wire. ``continues`` marks a block of a fast-read packet that follows the
    previous block without its own Return Delay Time."""

    servo: EmulatedServo
    data: bytes
    continues: bool = False


@dataclass(slots=True)
class Outcome:
    """Replies in wire order plus deferred actions (applied after the replies are built)."""

    replies: list[Reply]
    reboot: list[EmulatedServo]
    reset: list[tuple[EmulatedServo, int]]
    ids_changed: bool = False


def error_byte(servo: EmulatedServo, number: int) -> int:
    return number | (ALERT_BIT if servo.hardware_error else 0)


def answers(servo: EmulatedServo, instruction: int) -> bool:
    level = servo.status_return_level
    if instruction == Instruction.PING:
        return True
    if instruction in READS:
        return level >= LEVEL_READ
    return level >= 2


def status(
    out: Outcome,
    servo: EmulatedServo,
    inst: int,
    number: int,
    data: bytes = b"",
    sid: int | None = None,
    answer: bool | None = None,
) -> None:
    if answer if answer is not None else answers(servo, inst):
        out.replies.append(
            Reply(servo, build_status(servo.id if sid is None else sid, error_byte(servo, number), data))
        )


def servos_with(by_id: dict[int, list[EmulatedServo]], sid: int) -> list[EmulatedServo]:
    return by_id.get(sid, [])
