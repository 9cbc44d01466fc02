"""What calibration needs to know about a servo before measuring it: the head's view of the actuator.

The controller builds these from a head profile (``servoface.sim.heads.load_head``); calibration never imports sim.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from servoface.calibration.errors import CalibrationError

Kind = Literal["joint", "anchor"]


@dataclass(frozen=True)
class ServoSpec:
    """One actuator as the head profile describes it.

    ``lower``/``upper``/``neutral`` are targets in ``unit`` (deg for a joint, mm of pull for a skin anchor).
    ``direction`` (+1/-1) is only a default for generated (built-in) calibrations: a measured calibration
    learns it from the points.
    """

    role: str
    servo_id: int
    model: str
    unit: Literal["deg", "mm"]
    lower: float
    upper: float
    neutral: float
    kind: Kind
    direction: int = 1

    def __post_init__(self) -> None:
        who = f"servo '{self.role}' (id {self.servo_id})"
        if not self.role:
            raise CalibrationError("servo spec: role must be a non-empty string")
        if not 0 <= self.servo_id <= 252:
            raise CalibrationError(f"{who}: id must be 0..252")
        if self.unit not in ("deg", "mm"):
            raise CalibrationError(f"{who}: unit {self.unit!r} must be 'deg' or 'mm'")
        if self.kind not in ("joint", "anchor"):
            raise CalibrationError(f"{who}: kind {self.kind!r} must be 'joint' or 'anchor'")
        values = (self.lower, self.neutral, self.upper)
        if not all(math.isfinite(v) for v in values) or not self.lower <= self.neutral <= self.upper:
            raise CalibrationError(
                f"{who}: range {self.lower}..{self.upper} with neutral {self.neutral} must be finite "
                "with lower <= neutral <= upper"
            )
        if not self.lower < self.upper:
            raise CalibrationError(f"{who}: lower {self.lower} must be < upper {self.upper}")
        if self.direction not in (1, -1):
            raise CalibrationError(f"{who}: direction {self.direction} must be +1 or -1")


def default_direction(role: str) -> int:
    """Mirrored mounting: servos on the head's right side (``_r``) turn the other way."""
    return -1 if role.endswith("_r") else 1
