"""The gate's report object: accept / clip / reject, the goals to send, and every check that fired."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

VerdictKind = Literal["accept", "clip", "reject"]
CheckName = Literal[
    "input",
    "limit",
    "speed",
    "accel",
    "health",
    "coupling",
    "collision",
    "strain",
    "flip",
    "hold",
]


@dataclass(frozen=True)
class Finding:
    """One check that fired. ``servo_id``/``role`` name the servo when the check is per servo;
    ``parts`` name the rigid parts of a collision; ``value`` and ``limit`` are in ``unit``."""

    check: CheckName
    message: str
    role: str | None = None
    servo_id: int | None = None
    value: float | None = None
    limit: float | None = None
    unit: str = ""
    parts: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"[{self.check}] {self.message}"


@dataclass(frozen=True)
class Verdict:
    """What the gate decided for one requested command.

    ``goals_tick`` is what may be sent (servo id -> tick, every servo): the request (accept), the nearest
    safe command found (clip) or the last safe command (reject = hold). ``findings`` lists every check that
    fired on the request, plus, for a clip, why it was scaled back. ``step_fraction`` is the share of the
    requested step that was kept (1 for accept, 0 for reject; for a clip, the share of the servos it slowed:
    the servos that cannot move what the request failed on keep their whole clamped step, see
    `TwinGate._uninvolved`).
    """

    kind: VerdictKind
    goals_tick: dict[int, int]
    findings: tuple[Finding, ...] = ()
    step_fraction: float = 1.0
    requested_tick: dict[int, int] = field(default_factory=dict)

    @property
    def accepted(self) -> bool:
        return self.kind == "accept"

    @property
    def checks(self) -> tuple[str, ...]:
        """Names of the checks that fired, without repeats, in order of first firing."""
        return tuple(dict.fromkeys(f.check for f in self.findings))

    def reasons(self) -> list[str]:
        """One line per finding, for logs and the CLI."""
        return [str(f) for f in self.findings]

    def __str__(self) -> str:
        head = f"{self.kind} (step kept {self.step_fraction:.2f})"
        return "\n".join([head, *("  " + r for r in self.reasons())])
