"""The emulated chain a test talks to: in this process (`LocalChain`) or served on a pty by another
process (`ServedChain`, in ``served_chain``). Both have the same test-side interface: ``port`` to hand to
the code under test, fault injection scriptable in chain time, a manual clock, hand moves, and ``record()``
of what reached the servos."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from servoface.testing.errors import TestKitConfigError
from servoface.testing.record import WireRecord

CLOCKS = ("real", "manual")
TRANSPORTS = ("inprocess", "pty")


@dataclass(frozen=True)
class ChainSpec:
    """What to emulate: ``servos`` as (id, model) pairs, the bus and clock settings, start positions."""

    servos: tuple[tuple[int, str], ...]
    baud: int = 1_000_000
    clock: str = "real"
    wire_time: bool = True
    goal_limit: str = "reject"
    positions_tick: Mapping[int, int] = field(default_factory=dict)  # powered-up positions (torque off)

    def __post_init__(self) -> None:
        if not self.servos:
            raise TestKitConfigError("chain: servos is empty; expected at least one (id, model)")
        if self.clock not in CLOCKS:
            raise TestKitConfigError(f"chain: clock {self.clock!r}; expected one of {CLOCKS}")
        if self.clock == "manual" and self.wire_time:
            raise TestKitConfigError(
                "chain: clock='manual' needs wire_time=False (replies would wait for a clock nobody advances)"
            )

    def describe(self) -> dict[str, Any]:
        """The JSON description `servoface.testing.served` takes."""
        return {
            "servos": [list(s) for s in self.servos],
            "baud": self.baud,
            "clock": self.clock,
            "wire_time": self.wire_time,
            "goal_limit": self.goal_limit,
            "positions": {str(k): int(v) for k, v in self.positions_tick.items()},
        }


def fault_start_s(now_s: float, at_s: float | None, after_s: float | None) -> float | None:
    """Chain time a fault starts: ``at_s`` (absolute chain time) or ``after_s`` from now (None = now)."""
    if at_s is not None and after_s is not None:
        raise TestKitConfigError("inject: give at_s (chain time) or after_s (from now), not both")
    if after_s is not None:
        if after_s < 0:
            raise TestKitConfigError(f"inject: after_s {after_s}; expected >= 0")
        return now_s + float(after_s)
    return None if at_s is None else float(at_s)


class LocalChain:
    """An in-process `RecordingChain`; ``port`` is the chain object itself (what ``open_bus`` and
    ``Face.open(port=...)`` take), ``chain`` gives the whole emulator API."""

    transport = "inprocess"

    def __init__(self, spec: ChainSpec) -> None:
        from servoface.testing.recording_chain import RecordingChain

        self.spec = spec
        self.chain = RecordingChain.create(
            list(spec.servos), baud=spec.baud, wire_time=spec.wire_time, clock=spec.clock, goal_limit=spec.goal_limit
        )
        for sid, tick in spec.positions_tick.items():
            self.chain.servo(sid).move_by_hand(float(tick))

    @property
    def port(self) -> Any:
        return self.chain

    @property
    def path(self) -> str | None:
        return None

    @property
    def ids(self) -> list[int]:
        return [sid for sid, _ in self.spec.servos]

    @property
    def time_s(self) -> float:
        return float(self.chain.time_s)

    def advance(self, dt_s: float) -> None:
        self.chain.advance(dt_s)

    def inject(
        self,
        servo_id: int,
        kind: str,
        *,
        at_s: float | None = None,
        after_s: float | None = None,
        duration_s: float | None = None,
        **options: float,
    ) -> None:
        """Schedule an emulator fault (``servoface.hardware.emulator.FAULT_KINDS``) on ``servo_id``, from
        chain time ``at_s`` or ``after_s`` from now (default now), for ``duration_s`` (None = until cleared)."""
        start = fault_start_s(self.time_s, at_s, after_s)
        self.chain.faults.inject(servo_id, kind, start_s=start, duration_s=duration_s, **options)

    def clear_faults(self, servo_id: int | None = None, kind: str | None = None) -> None:
        self.chain.faults.clear(servo_id, kind)

    def move_by_hand(self, servo_id: int, tick: float) -> None:
        self.chain.servo(servo_id).move_by_hand(tick)

    def set_obstacle(self, servo_id: int, tick: float | None) -> None:
        self.chain.set_obstacle(servo_id, tick)

    def set_input_voltage(self, servo_id: int | None, volts: float) -> None:
        self.chain.set_input_voltage(servo_id, volts)

    def read_register(self, servo_id: int, name: str) -> int:
        return int(self.chain.servo(servo_id).read_register(name))

    def write_register(self, servo_id: int, name: str, value: int) -> None:
        self.chain.servo(servo_id).write_register(name, value)

    def record(self) -> WireRecord:
        record: WireRecord = self.chain.record("in-process emulator")
        return record

    def goal_writes(self) -> list[tuple[float, int, int]]:
        return list(self.record().goal_writes())

    def close(self) -> None:
        self.chain.close()

    def __enter__(self) -> LocalChain:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
