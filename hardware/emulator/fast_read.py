"""Fast Sync Read / Fast Bulk Read: one combined status packet, ``FF FF FD 00 FE LEN 55`` then per device
``ERR ID data CRC`` (reference sheet §5); each block is put on the wire by its own servo."""

from __future__ import annotations

from collections.abc import Sequence

from servoface.hardware.emulator.answers import Outcome, Reply, answers
from servoface.hardware.emulator.crc import crc16, crc16_even, crc16_own_tail
from servoface.hardware.emulator.models import FAST_READ_MIN_FIRMWARE
from servoface.hardware.emulator.packet import ALERT_BIT, BROADCAST_ID, HEADER, Instruction, stuff
from servoface.hardware.emulator.servo import EmulatedServo


def needs_stuffing(logical: bytes) -> bool:
    """Whether the combined reply's body (``55`` then ``logical`` less its CRC) holds ``FF FF FD``: the same
    as ``b"\\xff\\xff\\xfd" in bytes((0x55,)) + logical[:-2]`` (0x55 cannot start it), without the copies."""
    return logical.find(b"\xff\xff\xfd", 0, len(logical) - 2) >= 0


def _fast_read(
    out: Outcome, requests: list[tuple[int, int, int]], by_id: dict[int, list[EmulatedServo]], inst: int
) -> None:
    """One combined packet: ``FF FF FD 00 FE LEN 55`` then per device ``ERR ID data CRC``; each block's CRC is
    the running CRC of the packet so far, so the last one is the packet CRC (reference sheet §5). A servo
    whose firmware predates the instruction (`FAST_READ_MIN_FIRMWARE`) ignores it, like an absent one: its
    block never appears (the first one silent: no packet at all)."""
    blocks: list[tuple[EmulatedServo | None, bytes]] = []
    get = by_id.get  # `servos_with` and `error_byte`, inlined: once per servo per read
    for sid, addr, length in requests:
        servos = get(sid)
        if not servos or servos[0].firmware_version < FAST_READ_MIN_FIRMWARE:
            blocks.append((None, bytes(length + 2)))
            continue
        servo = servos[0]
        err, data = servo.read_bytes(addr, length)
        if len(data) < length:
            data = data + bytes(length - len(data))
        blocks.append((servo, bytes((err | (ALERT_BIT if servo.hardware_error else 0), servo.id)) + data))
    lead = blocks[0][0] if blocks else None
    if lead is None or not answers(lead, inst):
        return
    length_field = 1 + sum(len(b) + 2 for _, b in blocks)
    head = HEADER + bytes((BROADCAST_ID, length_field & 0xFF, length_field >> 8, 0x55))
    parts: list[tuple[EmulatedServo | None, bytes]] = []
    crc = crc16(head)
    for owner, block in blocks:  # crc16 of the block, then of its own CRC's two bytes (crc.py: same values)
        crc = crc16_even(block, crc) if not len(block) & 1 else crc16(block, crc)
        parts.append((owner, block + bytes((crc & 0xFF, crc >> 8))))
        crc = crc16_own_tail(crc)
    logical = b"".join(p for _, p in parts)
    if needs_stuffing(logical):
        # rare: the body needs byte stuffing; send it as one stuffed packet (the SDK does not unstuff it)
        body = stuff(bytes((0x55,)) + logical[:-2])
        packet = HEADER + bytes((BROADCAST_ID, (len(body) + 2) & 0xFF, (len(body) + 2) >> 8)) + body
        crc = crc16(packet)
        out.replies.append(Reply(lead, packet + bytes((crc & 0xFF, crc >> 8))))
        return
    first = True
    for owner, part in parts:
        if owner is None:
            continue  # absent: its bytes never appear, the host sees a short, corrupt packet
        out.replies.append(Reply(owner, (head + part) if first else part, continues=not first))
        first = False


def fast_sync_read(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    if pid != BROADCAST_ID or len(params) < 5:
        return
    addr = params[0] | params[1] << 8
    length = params[2] | params[3] << 8
    _fast_read(out, [(sid, addr, length) for sid in params[4:]], by_id, Instruction.FAST_SYNC_READ)


def fast_bulk_read(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    if pid != BROADCAST_ID or len(params) % 5 or not params:
        return
    req = [
        (params[i], params[i + 1] | params[i + 2] << 8, params[i + 3] | params[i + 4] << 8)
        for i in range(0, len(params), 5)
    ]
    _fast_read(out, req, by_id, Instruction.FAST_BULK_READ)
