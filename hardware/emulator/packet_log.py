"""The chain's packet log: every instruction packet received (CRC valid), and decoders over it."""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

from servoface.hardware.emulator.packet import Instruction

_WRITES = (Instruction.WRITE, Instruction.REG_WRITE)


class LogEntry(NamedTuple):
    """One decoded instruction packet the chain received (CRC valid), at its arrival time."""

    t_s: float
    id: int
    instruction: int
    params: bytes


def register_writes(
    log: Iterable[LogEntry], address: int, size: int, *, signed: bool = True
) -> list[tuple[float, int, int]]:
    """(t_s, servo_id, value) for every write covering the whole register at ``address`` (Write, Reg Write,
    Sync Write, Bulk Write). A broadcast Write is reported with id 254."""
    out: list[tuple[float, int, int]] = []
    end = address + size

    def value(chunk: bytes) -> int:
        return int.from_bytes(chunk, "little", signed=signed)

    for t, pid, inst, p in log:
        if inst in _WRITES and len(p) > 2:
            start = p[0] | p[1] << 8
            if start <= address and start + len(p) - 2 >= end:
                out.append((t, pid, value(p[2 + address - start : 2 + end - start])))
        elif inst == Instruction.SYNC_WRITE and len(p) >= 4:
            start = p[0] | p[1] << 8
            length = p[2] | p[3] << 8
            if start <= address and start + length >= end and length:
                off = 4
                while off + 1 + length <= len(p):
                    out.append((t, p[off], value(p[off + 1 + address - start : off + 1 + end - start])))
                    off += 1 + length
        elif inst == Instruction.BULK_WRITE:
            off = 0
            while off + 5 <= len(p):
                sid = p[off]
                start = p[off + 1] | p[off + 2] << 8
                length = p[off + 3] | p[off + 4] << 8
                data = p[off + 5 : off + 5 + length]
                if start <= address and start + length >= end and len(data) == length:
                    out.append((t, sid, value(data[address - start : end - start])))
                off += 5 + length
    return out
