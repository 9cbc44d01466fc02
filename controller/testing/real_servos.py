"""Real servos instead of the emulator: the port, baud and servos given by ``--servoface-port`` (or
``SERVOFACE_PORT``) and friends, and their end state read back over the bus (the write history of a real
bus cannot be seen; the wire checks say so instead of passing)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from servoface.testing.errors import TestKitConfigError
from servoface.testing.record import ServoEnd, WireRecord

READ_TRIES = 3  # a reply lost on a real (or busy) line is asked for again
ENV = {
    "port": "SERVOFACE_PORT",
    "baud": "SERVOFACE_BAUD",
    "ids": "SERVOFACE_IDS",
    "head": "SERVOFACE_HEAD",
    "model": "SERVOFACE_MODEL",
}


@dataclass(frozen=True)
class RealRig:
    """What the command line / environment says about the servos on the bench."""

    port: str | None
    baud: int
    ids: str | None
    head: str | None
    model: str | None

    @classmethod
    def from_options(cls, option: Any) -> RealRig:
        def get(name: str) -> str | None:
            value = getattr(option, f"servoface_{name}", None)
            return value if value not in (None, "") else (os.environ.get(ENV[name]) or None)

        baud = get("baud") or "1000000"
        try:
            baud_bps = int(baud)
        except ValueError as err:
            raise TestKitConfigError(
                f"--servoface-baud / SERVOFACE_BAUD {baud!r}: expected bits per second, e.g. 1000000"
            ) from err
        return cls(get("port"), baud_bps, get("ids"), get("head"), get("model"))

    def describe(self) -> str:
        what = f"head {self.head}" if self.head else f"ids {self.ids or '1-4'}"
        return f"real servos on {self.port} at {self.baud} bps ({what})"


class RealServos:
    """The chain-side object of a hardware test: ``port`` is the device path; ``record()`` reads every
    servo's torque, positions and hardware error over ``bus`` (the test's own, or one opened for it)."""

    transport = "real"

    def __init__(self, port: str, baud: int, ids: list[int]) -> None:
        self.port = self.path = port
        self.baud = baud
        self.ids = ids
        self.bus: Any = None  # the dxl_bus fixture registers its bus here so reads do not open a second one

    def record(self) -> WireRecord:
        from servoface.hardware.bus import open_bus
        from servoface.hardware.errors import BusCorruptError, BusTimeoutError
        from servoface.hardware.registers import Register

        registers = [
            Register.TORQUE_ENABLE,
            Register.HARDWARE_ERROR_STATUS,
            Register.GOAL_POSITION,
            Register.PRESENT_POSITION,
        ]

        def read(sid: int) -> dict[Any, int]:
            for attempt in range(READ_TRIES):
                try:
                    values: dict[Any, int] = bus.read_many(sid, registers)
                    return values
                except (BusTimeoutError, BusCorruptError):
                    if attempt == READ_TRIES - 1:
                        raise
            raise AssertionError("unreachable")  # pragma: no cover

        bus: Any = self.bus if self.bus is not None and self.bus.is_open else None
        own = bus is None
        if own:
            bus = open_bus("dynamixel", port=self.port, baud=self.baud)
        try:
            end = {}
            for sid in self.ids:
                values = read(sid)
                end[sid] = ServoEnd(
                    sid,
                    bool(values[Register.TORQUE_ENABLE]),
                    int(values[Register.PRESENT_POSITION]),
                    int(values[Register.GOAL_POSITION]),
                    int(values[Register.HARDWARE_ERROR_STATUS]),
                )
        finally:
            if own:
                bus.close()
        return WireRecord(source=f"real servos on {self.port}", end=end, goals=None, torque_writes=None)
