"""The servo bus interface (python-can style) and the factory that picks a backend by name.

Everything in servoface talks to a chain through `ServoBus`; only `servoface.hardware.dynamixel_bus` touches
dynamixel-sdk. Backends are imported lazily by `open_bus`, so importing this module costs nothing.

Error contract, shared by every backend (and checked by one contract test suite):

- no reply in time -> `BusTimeoutError`; malformed reply / bad CRC -> `BusCorruptError`;
- a status packet with a non-zero error number -> `ServoStatusError`;
- a status packet with only the Alert bit (0x80) -> the call succeeds and the id is added to
  `alerts` (read Hardware Error Status to learn why); sync and fast sync reads record it the same way,
  from each servo's error byte, so the per-frame position read carries every servo's alarm;
- the port itself fails -> `BusDisconnectedError`; use after close -> `BusClosedError`;
- a sync/bulk read is all-or-nothing: one silent servo fails the whole call (`BusTimeoutError` whose
  ``servo_ids`` lists the ids asked for). The driver falls back to single reads to find the silent one.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any, Protocol, runtime_checkable

from servoface.hardware.registers import Register


@dataclass(frozen=True)
class PingReply:
    """What a servo says to a ping."""

    servo_id: int
    model_number: int
    firmware_version: int


@dataclass(frozen=True)
class BusCounters:
    """A frozen copy of `BusStats` (what a `ChainSnapshot` carries)."""

    transactions: int = 0
    timeouts: int = 0
    corrupt: int = 0
    status_errors: int = 0
    alerts: int = 0
    bytes_written: int = 0
    stray: int = 0  # status packets of another id skipped (late replies to an earlier instruction)


@dataclass
class BusStats:
    """Running counters of one bus (plain counters, owned by the bus thread)."""

    transactions: int = 0
    timeouts: int = 0
    corrupt: int = 0
    status_errors: int = 0
    alerts: int = 0
    bytes_written: int = 0
    stray: int = 0  # status packets of another id skipped (late replies to an earlier instruction)

    def copy(self) -> BusCounters:
        """A frozen copy, equal to ``BusCounters(**vars(self))`` (built without the frozen ``__init__``'s
        per-field setattr: one per cycle, into the snapshot)."""
        counters: BusCounters = object.__new__(BusCounters)
        object.__setattr__(counters, "__dict__", self.__dict__.copy())
        return counters


@runtime_checkable
class ServoBus(Protocol):
    """One Protocol 2.0 chain behind one port. Not thread-safe: one thread owns it (see `Driver`)."""

    port_name: str
    baud: int
    stats: BusStats
    alerts: set[int]

    @property
    def is_open(self) -> bool: ...

    def open(self) -> None: ...

    def close(self) -> None: ...

    def __enter__(self) -> ServoBus: ...

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None: ...

    def ping(self, servo_id: int) -> PingReply: ...

    def broadcast_ping(self) -> dict[int, PingReply]: ...

    def read(self, servo_id: int, register: Register) -> int: ...

    def read_many(self, servo_id: int, registers: Sequence[Register]) -> dict[Register, int]: ...

    def write(self, servo_id: int, register: Register, value: int) -> None: ...

    def sync_read(
        self, servo_ids: Sequence[int], registers: Sequence[Register], *, fast: bool = False
    ) -> dict[int, dict[Register, int]]: ...

    def sync_read_start(self, servo_ids: Sequence[int], registers: Sequence[Register], *, fast: bool = False) -> None:
        """Send the read instruction only; `sync_read_finish` collects the replies (the caller computes
        meanwhile). ``sync_read`` is exactly start + finish."""
        ...

    def sync_read_finish(self, *, patient: bool = False) -> dict[int, dict[Register, int]]: ...

    def sync_write(self, register: Register, values: Mapping[int, int]) -> None: ...

    def bulk_read(
        self, requests: Mapping[int, Sequence[Register]], *, fast: bool = False
    ) -> dict[int, dict[Register, int]]: ...

    def bulk_write(self, writes: Mapping[int, Mapping[Register, int]]) -> None: ...

    def reboot(self, servo_id: int) -> None: ...

    def reopen(self) -> None: ...


@dataclass(frozen=True)
class BackendInfo:
    module: str
    factory: str
    aliases: tuple[str, ...] = field(default_factory=tuple)


BACKENDS: dict[str, BackendInfo] = {
    # the real Dynamixel bus; ``port`` is a device path (or a pty path), or an emulated chain object
    "dynamixel": BackendInfo("servoface.hardware.dynamixel_bus", "DynamixelBus"),
    # the same bus class, in-process against an emulated chain (``chain=`` or ``port=`` a ServoChain)
    "emulator": BackendInfo("servoface.hardware.dynamixel_bus", "DynamixelBus", ("memory",)),
}


def backend_names() -> list[str]:
    names = list(BACKENDS)
    for info in BACKENDS.values():
        names += list(info.aliases)
    return names


def open_bus(interface: str, port: Any = None, baud: int = 1_000_000, **kwargs: Any) -> ServoBus:
    """Open a bus by interface name: ``open_bus("dynamixel", port="/dev/ttyUSB0", baud=1_000_000)``.

    ``open_bus("dynamixel", port=chain)`` or ``open_bus("emulator", chain=chain)`` talk to an emulated
    chain in-process: the stock SDK's packet, CRC and timeout code runs over the emulator's serial object.
    Extra keyword arguments go to the backend (e.g. ``latency_timer_ms``, ``warn_latency``).
    """
    info = None
    for name, candidate in BACKENDS.items():
        if interface == name or interface in candidate.aliases:
            info = candidate
    if info is None:
        raise ValueError(f"unknown bus interface {interface!r}; expected one of {backend_names()}")
    if "chain" in kwargs:
        if port is not None:
            raise ValueError("open_bus: give either port= or chain=, not both")
        port = kwargs.pop("chain")
    if port is None:
        raise ValueError(f"open_bus({interface!r}): port is required (a device path or an emulated chain)")
    if interface != "dynamixel" and isinstance(port, str):
        raise ValueError(f"open_bus({interface!r}): expects chain=<ServoChain>, got a path {port!r}")
    module = importlib.import_module(info.module)
    bus: ServoBus = getattr(module, info.factory)(port, baud=baud, **kwargs)
    bus.open()
    return bus


def ids_from_spec(text: str) -> list[int]:
    """Parse an id list like ``"1-4,7,10-12"`` into sorted unique ids (each 0..252)."""
    ids: set[int] = set()
    for part in filter(None, (p.strip() for p in text.split(","))):
        lo_s, sep, hi_s = part.partition("-")
        try:
            lo = int(lo_s)
            hi = int(hi_s) if sep else lo
        except ValueError as err:
            raise ValueError(f"bad id range {part!r} in {text!r}; expected e.g. '1-4,7'") from err
        if not 0 <= lo <= hi <= 252:
            raise ValueError(f"id range {part!r} outside 0..252 (or reversed)")
        ids.update(range(lo, hi + 1))
    if not ids:
        raise ValueError(f"no ids in {text!r}")
    return sorted(ids)


def check_ids(servo_ids: Iterable[int]) -> list[int]:
    """Validate servo ids (ints 0..252, no duplicates) and return them as a list, in order."""
    out = list(servo_ids)
    for sid in out:
        if isinstance(sid, bool) or not isinstance(sid, int) or not 0 <= sid <= 252:
            raise ValueError(f"servo id {sid!r} is not an int in 0..252")
    if len(set(out)) != len(out):
        raise ValueError(f"duplicate servo ids in {out}")
    return out
