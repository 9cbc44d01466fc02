"""Waters-style muscles of the skin: linear, sheet, sphincter, and the eyelid region.

Each muscle is a frozen dataclass in the head frame (mm) with ``from_mapping(name, data, where)`` that
parses one ``[muscles.<name>]`` table of a head profile (``type`` = "linear" | "sheet" | "sphincter" |
"eyelid") and raises ``servoface.sim.errors.HeadProfileError`` naming the key path. Fields:

- linear:    attachment_mm, insertion_mm, zone_deg (45), rs_mm (|ip - ap|), rf_mm (1.5 rs),
             max_contraction (0.25)
- sheet:     attachment_mm, attachment_end_mm, insertion_mm, insertion_end_mm, width_mm, max_contraction,
             optional falloff_mm, depth_mm
- sphincter: centre_mm, semi_axes_mm ([major, minor] or [major, minor, depth]), max_contraction,
             optional major_axis, normal, falloff ("corrected" | "printed")
- eyelid:    centre_mm, radius_mm, joint, optional part ("upper" | "lower"), reach_mm, thickness_mm, axis

The field math is in each module; ``servoface.sim.muscles.field.MuscleField`` precomputes them on a rest mesh.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from servoface.sim.errors import HeadProfileError
from servoface.sim.muscles.eyelid import EyelidMuscle
from servoface.sim.muscles.linear import LinearMuscle
from servoface.sim.muscles.sheet import SheetMuscle
from servoface.sim.muscles.sphincter import SphincterMuscle

Muscle = LinearMuscle | SheetMuscle | SphincterMuscle | EyelidMuscle

MUSCLE_TYPES: dict[str, type[LinearMuscle] | type[SheetMuscle] | type[SphincterMuscle] | type[EyelidMuscle]] = {
    "linear": LinearMuscle,
    "sheet": SheetMuscle,
    "sphincter": SphincterMuscle,
    "eyelid": EyelidMuscle,
}


def muscle_from_mapping(name: str, data: Mapping[str, Any], where: str | None = None) -> Muscle:
    """Parse one muscle table, dispatching on its ``type`` key."""
    where = where or f"muscles.{name}"
    if not isinstance(data, Mapping):
        raise HeadProfileError(f"{where}: expected a table of muscle fields, got {data!r}")
    kind = data.get("type")
    if kind not in MUSCLE_TYPES:
        raise HeadProfileError(f"{where}.type: expected one of {sorted(MUSCLE_TYPES)}, got {kind!r}")
    return MUSCLE_TYPES[kind].from_mapping(name, data, where)


def muscles_from_mapping(data: Mapping[str, Any], where: str = "muscles") -> dict[str, Muscle]:
    """Parse a whole ``[muscles]`` table: {name: muscle}."""
    if not isinstance(data, Mapping):
        raise HeadProfileError(f"{where}: expected a table of muscles, got {data!r}")
    return {name: muscle_from_mapping(name, spec, f"{where}.{name}") for name, spec in data.items()}


__all__ = [
    "MUSCLE_TYPES",
    "EyelidMuscle",
    "LinearMuscle",
    "Muscle",
    "SheetMuscle",
    "SphincterMuscle",
    "muscle_from_mapping",
    "muscles_from_mapping",
]
