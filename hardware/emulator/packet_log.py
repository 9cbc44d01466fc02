"""The chain's packet log: every instruction packet received (CRC valid), kept in a bounded ring with
absolute indexes, and decoders over it."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import NamedTuple, overload

from servoface.hardware.emulator.packet import Instruction

_WRITES = (Instruction.WRITE, Instruction.REG_WRITE)


class LogEntry(NamedTuple):
    """One decoded instruction packet the chain received (CRC valid), at its arrival time."""

    t_s: float
    id: int
    instruction: int
    params: bytes


class PacketLog:
    """The newest ``limit`` log entries (None: all), indexed by their absolute position in the chain's life.

    ``len(log)`` counts every packet ever logged; ``log[i]`` / ``log[a:b]`` take absolute indexes (what a
    reader saw as ``len(log)`` earlier still marks where it left off); entries older than ``first_index`` were
    dropped — past the limit the older half goes at once (amortised O(1) per packet), so a long run keeps at
    most ``limit`` entries (~240 bytes each for a Sync Write of 30 goals) however long it runs. Iterating
    gives the entries kept, oldest first."""

    def __init__(self, limit: int | None = None) -> None:
        if limit is not None and int(limit) < 2:
            from servoface.hardware.emulator.errors import EmulatorConfigError

            raise EmulatorConfigError(f"log_limit {limit}: expected None (keep all) or at least 2 entries")
        self.limit = None if limit is None else int(limit)
        self._items: list[LogEntry] = []
        self._dropped = 0

    @property
    def first_index(self) -> int:
        """Absolute index of the oldest entry kept (= entries dropped so far)."""
        return self._dropped

    def append(self, entry: LogEntry) -> None:
        items = self._items
        items.append(entry)
        if self.limit is not None and len(items) > self.limit:
            drop = len(items) - self.limit // 2  # keep the newer half
            del items[:drop]
            self._dropped += drop

    def clear(self) -> None:
        """Drop every entry kept (indexes go on from where they were)."""
        self._dropped += len(self._items)
        self._items.clear()

    def kept(self) -> list[LogEntry]:
        """A copy of the entries kept, oldest first."""
        return list(self._items)

    def __len__(self) -> int:
        return self._dropped + len(self._items)

    def __iter__(self) -> Iterator[LogEntry]:
        return iter(list(self._items))

    @overload
    def __getitem__(self, index: int) -> LogEntry: ...

    @overload
    def __getitem__(self, index: slice) -> list[LogEntry]: ...

    def __getitem__(self, index: int | slice) -> LogEntry | list[LogEntry]:
        if isinstance(index, slice):
            start, stop, step = index.indices(len(self))
            if step != 1:
                return self.kept()[max(0, start - self._dropped) : max(0, stop - self._dropped) : step]
            return self._items[max(0, start - self._dropped) : max(0, stop - self._dropped)]
        i = index + len(self) if index < 0 else index
        if not self._dropped <= i < len(self):
            raise IndexError(f"packet log index {index}: kept are {self._dropped}..{len(self) - 1}")
        return self._items[i - self._dropped]

    def __delitem__(self, index: slice) -> None:
        """``del log[:]`` / ``del log[:n]``: drop the oldest entries (only a prefix can go)."""
        if not isinstance(index, slice) or index.step not in (None, 1) or index.start not in (None, 0):
            raise TypeError("only the oldest entries can be dropped from a packet log: del log[:n]")
        stop = len(self) if index.stop is None else min(len(self), index.indices(len(self))[1])
        n = max(0, stop - self._dropped)
        del self._items[:n]
        self._dropped += n


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
