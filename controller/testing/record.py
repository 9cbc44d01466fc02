"""What reached the servos, as the emulator saw it: goal writes with the servo's state when each arrived,
torque writes, and every servo's state at the end. Plain data, JSON round-trip (the pty chain lives in
another process and sends its record over a pipe)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any


@dataclass(frozen=True, slots=True)
class GoalWrite:
    """One Goal Position a servo was sent (Write, Reg Write, Sync Write or Bulk Write), at its arrival time.

    ``torque_on`` and ``present_tick`` are the servo's state just before the packet took effect; ``seq``
    numbers the write packets (it orders goal and torque writes)."""

    seq: int
    t_s: float
    servo_id: int
    goal_tick: int
    torque_on: bool
    present_tick: int


@dataclass(frozen=True, slots=True)
class TorqueWrite:
    """One Torque Enable write (1 on, 0 off) a servo was sent."""

    seq: int
    t_s: float
    servo_id: int
    value: int


@dataclass(frozen=True, slots=True)
class ServoEnd:
    """A servo's state when the record was taken (registers read on the emulator, or over a real bus)."""

    servo_id: int
    torque_on: bool
    present_tick: int
    goal_tick: int
    hardware_error: int
    model: str = ""


@dataclass(frozen=True, slots=True)
class WireRecord:
    """The record of one chain. ``goals``/``torque_writes`` are None when the wire could not be observed
    (real servos: only their end state can be read back)."""

    source: str
    end: dict[int, ServoEnd]
    goals: tuple[GoalWrite, ...] | None
    torque_writes: tuple[TorqueWrite, ...] | None
    time_s: float = 0.0

    @property
    def observed(self) -> bool:
        """True when every write on the wire was recorded (emulator), False for real servos."""
        return self.goals is not None

    def goal_writes(self) -> list[tuple[float, int, int]]:
        """(t_s, servo_id, goal_tick) per goal, in wire order (empty when not observed)."""
        return [(g.t_s, g.servo_id, g.goal_tick) for g in self.goals or ()]

    def to_json(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "time_s": self.time_s,
            "end": [asdict(e) for e in self.end.values()],
            "goals": None if self.goals is None else [list(asdict(g).values()) for g in self.goals],
            "torque_writes": (
                None if self.torque_writes is None else [list(asdict(w).values()) for w in self.torque_writes]
            ),
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> WireRecord:
        end = {int(e["servo_id"]): ServoEnd(**e) for e in data["end"]}
        goals = data["goals"]
        writes = data["torque_writes"]
        return cls(
            source=str(data["source"]),
            end=end,
            goals=None
            if goals is None
            else tuple(GoalWrite(int(q), float(t), int(i), int(g), bool(on), int(p)) for q, t, i, g, on, p in goals),
            torque_writes=None
            if writes is None
            else tuple(TorqueWrite(int(q), float(t), int(i), int(v)) for q, t, i, v in writes),
            time_s=float(data.get("time_s", 0.0)),
        )
