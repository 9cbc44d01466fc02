"""Control tables as data: one :class:`Register` per field (address, size, sign, access, area, default, unit).

A second transcription of the ROBOTIS e-manual pages (X-series / MX(2.0) layout), independent of the
driver's register enum. ``ControlTable`` indexes registers by name and by address for byte-level access.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field, replace
from typing import Literal

from servoface.hardware.emulator.errors import RegisterError

Access = Literal["R", "RW"]
Area = Literal["EEPROM", "RAM"]
EEPROM_END = 64  # addresses below this are EEPROM: writable only with Torque Enable = 0


@dataclass(frozen=True, slots=True)
class Register:
    """One control-table field. ``minimum``/``maximum`` bound writes (Data Range Error outside)."""

    name: str
    address: int
    size: int
    access: Access
    default: int = 0
    signed: bool = False
    unit: str = ""
    minimum: int | None = None
    maximum: int | None = None

    @property
    def area(self) -> Area:
        return "EEPROM" if self.address < EEPROM_END else "RAM"

    end: int = field(init=False, repr=False, compare=False)  # one past the last byte

    def __post_init__(self) -> None:
        object.__setattr__(self, "end", self.address + self.size)

    def decode(self, raw: bytes | bytearray) -> int:
        return int.from_bytes(raw, "little", signed=self.signed)

    def encode(self, value: int) -> bytes:
        """Little-endian bytes; negative values wrap (two's complement) whatever ``signed`` says."""
        return (value & ((1 << (8 * self.size)) - 1)).to_bytes(self.size, "little")

    def in_range(self, value: int) -> bool:
        lo = self.minimum
        hi = self.maximum
        return (lo is None or value >= lo) and (hi is None or value <= hi)


def R(name: str, address: int, size: int, default: int = 0, *, signed: bool = False, unit: str = "") -> Register:
    """A read-only register."""
    return Register(name, address, size, "R", default, signed, unit)


def RW(
    name: str,
    address: int,
    size: int,
    default: int = 0,
    *,
    signed: bool = False,
    unit: str = "",
    lo: int | None = None,
    hi: int | None = None,
) -> Register:
    """A read-write register with an optional value range."""
    return Register(name, address, size, "RW", default, signed, unit, lo, hi)


class ControlTable:
    """The registers of one model, looked up by name or address; ``size`` is the memory image length."""

    def __init__(self, registers: Iterable[Register]) -> None:
        regs = sorted(registers, key=lambda r: r.address)
        self.registers: tuple[Register, ...] = tuple(regs)
        self._by_name: dict[str, Register] = {}
        self._by_address: dict[int, Register] = {}
        self.size = max(r.end for r in regs)
        # owner[a] = register covering byte a (None for gaps)
        self.owner: list[Register | None] = [None] * self.size
        for reg in regs:
            key = _key(reg.name)
            if key in self._by_name:
                raise RegisterError(f"register name {reg.name!r} appears twice in a control table")
            self._by_name[key] = reg
            self._by_address[reg.address] = reg
            for a in range(reg.address, reg.end):
                if self.owner[a] is not None:
                    raise RegisterError(f"register {reg.name!r} at {reg.address} overlaps {self.owner[a]}")
                self.owner[a] = reg
        # writable[a] is True if byte a belongs to an RW register
        self.writable: bytes = bytes(1 if r is not None and r.access == "RW" else 0 for r in self.owner)

    def __iter__(self) -> Iterator[Register]:
        return iter(self.registers)

    def __contains__(self, key: object) -> bool:
        if isinstance(key, int):
            return key in self._by_address
        return isinstance(key, str) and _key(key) in self._by_name

    def get(self, key: str | int) -> Register:
        """The register named ``key`` (case/space/underscore-insensitive) or starting at address ``key``."""
        if isinstance(key, int):
            reg = self._by_address.get(key)
        else:
            reg = self._by_name.get(_key(key))
        if reg is None:
            raise RegisterError(f"no register {key!r} in this control table")
        return reg

    def defaults_image(self) -> bytearray:
        image = bytearray(self.size)
        for reg in self.registers:
            image[reg.address : reg.end] = reg.encode(reg.default)
        return image

    def with_overrides(self, **defaults: int) -> ControlTable:
        """A copy with some defaults replaced (keys are register names with underscores)."""
        regs = {_key(r.name): r for r in self.registers}
        for name, value in defaults.items():
            key = _key(name)
            if key not in regs:
                raise RegisterError(f"cannot override default of unknown register {name!r}")
            regs[key] = replace(regs[key], default=value)
        return ControlTable(regs.values())


def _key(name: str) -> str:
    return name.lower().replace(" ", "").replace("_", "").replace("(", "").replace(")", "")
