"""The data model of a head: joints, rigid parts, skin, actuators and the servos behind them.

Frames and units (every head, built-in or user): millimetres; the head frame has its origin at the top of
the neck, +y up, +z forward (out of the face, towards a viewer), +x towards the head's own LEFT. Suffix
``_l`` / ``_r`` = the head's own left / right (so ``_l`` parts sit at x > 0). Angles in degrees, positive by
the right-hand rule about the joint axis.

This module is the contract shared by the face model, the twin gate, rendering and the controller: extend
it, do not rename what is here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

Vec3 = tuple[float, float, float]
FaceType = Literal["human", "dog"]


@dataclass(frozen=True)
class Joint:
    """A revolute joint. Joints form a tree through ``parent`` (another joint's name, or None = head base).

    ``pivot_mm`` and ``axis`` are given in the head frame with every joint at 0 deg.
    """

    name: str
    parent: str | None
    pivot_mm: Vec3
    axis: Vec3
    lower_deg: float
    upper_deg: float
    neutral_deg: float = 0.0


@dataclass(frozen=True)
class RigidPart:
    """A rigid mesh (skull, jaw, eyeball, eyelid, ear, tongue, neck) carried by a joint (None = head base).

    ``mesh`` is in the head frame at rest (all joints at 0 deg). ``color_rgba`` in 0..1.
    """

    name: str
    joint: str | None
    mesh: Any  # trimesh.Trimesh (kept untyped so this module imports without trimesh)
    color_rgba: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)
    collides: bool = True


@dataclass(frozen=True)
class Skin:
    """The skin mesh at rest, bound to the rig by linear-blend weights.

    vertices_mm: (n, 3) float, rest positions in the head frame.
    faces: (m, 3) int.
    weights: (n, J + 1) float, rows sum to 1; column 0 = head base, column j + 1 = ``joint_names[j]``.
    """

    vertices_mm: NDArray[np.float64]
    faces: NDArray[np.int64]
    joint_names: tuple[str, ...]
    weights: NDArray[np.float64]
    color_rgba: tuple[float, float, float, float] = (0.86, 0.70, 0.60, 1.0)
    vertex_colors_rgba: NDArray[np.float64] | None = None  # (n, 4) float 0..1 (lips, brows), optional


@dataclass(frozen=True)
class ServoRef:
    """The servo behind an actuator: Dynamixel id and model name (e.g. "XL330-M288")."""

    id: int
    model: str


@dataclass(frozen=True)
class JointActuator:
    """A servo that turns one or more joints by the same angle (e.g. both eyes' pan)."""

    role: str
    servo: ServoRef
    joints: tuple[str, ...]
    lower_deg: float
    upper_deg: float
    neutral_deg: float = 0.0
    kind: Literal["joint"] = "joint"


@dataclass(frozen=True)
class AnchorActuator:
    """A servo that pulls a skin anchor (a vertex of the skin) along a line of action.

    ``line`` is a unit vector in the head frame at rest; the target is the pull in mm along it.
    ``radius_mm`` is how far around the anchor the pull spreads when the twin poses the skin from pulls.
    """

    role: str
    servo: ServoRef
    vertex: int
    line: Vec3
    lower_mm: float
    upper_mm: float
    neutral_mm: float = 0.0
    radius_mm: float = 15.0
    kind: Literal["anchor"] = "anchor"


Actuator = JointActuator | AnchorActuator


@dataclass
class HeadPose:
    """A posed head: joint angles (deg, every joint of the head) and the skin offsets of the muscles.

    skin_offset_mm: (n, 3) float, displacement of each skin vertex in the rest frame, applied before skinning.
    """

    joint_deg: dict[str, float]
    skin_offset_mm: NDArray[np.float64]
    actuator_targets: dict[str, float] = field(default_factory=dict)  # role -> deg or mm


# --- muscles: placement only (the math lives in the face model) -----------------------------------------
# Waters-style muscles placed on the skin at rest, in the head frame (mm). See
# /work/shared/reference/muscle-models.md section 1 for the meaning of the parameters.


@dataclass(frozen=True)
class LinearMuscle:
    """A linear (vector) muscle: the bone end ``attachment_mm`` is fixed, the skin end ``insertion_mm`` moves.

    ``zone_deg`` = half-angle of the influence cone around attachment->insertion; ``rs_mm`` / ``rf_mm`` =
    fall-off start / finish radii measured from the attachment (Waters' R_s, R_f);
    ``max_contraction`` in 0..1.
    """

    name: str
    attachment_mm: Vec3
    insertion_mm: Vec3
    zone_deg: float
    rs_mm: float
    rf_mm: float
    max_contraction: float = 0.25
    type: Literal["linear"] = "linear"


@dataclass(frozen=True)
class SphincterMuscle:
    """A sphincter (orbicularis oris/oculi) squeezing skin towards ``centre_mm``.

    ``semi_axes_mm`` = (lx, ly) or (lx, ly, lz): the ellipse (ellipsoid) of influence, lx along
    ``major_axis``, ly along ``normal`` x ``major_axis``, lz along ``normal`` (depth band).
    ``falloff``: "corrected" (default), "printed" or "ring" (``servoface.sim.muscles.sphincter``).
    """

    name: str
    centre_mm: Vec3
    semi_axes_mm: tuple[float, ...]
    max_contraction: float = 0.25
    normal: Vec3 = (0.0, 0.0, 1.0)
    major_axis: Vec3 = (1.0, 0.0, 0.0)
    falloff: str = "corrected"
    type: Literal["sphincter"] = "sphincter"


@dataclass(frozen=True)
class SheetMuscle:
    """A sheet muscle with parallel fibres: attachment line (start..end) to insertion line (start..end).

    ``width_mm`` = the perpendicular half-width of influence around the sheet.
    """

    name: str
    attachment_mm: Vec3
    attachment_end_mm: Vec3
    insertion_mm: Vec3
    insertion_end_mm: Vec3
    width_mm: float
    max_contraction: float = 0.25
    type: Literal["sheet"] = "sheet"


Muscle = LinearMuscle | SphincterMuscle | SheetMuscle


@dataclass(frozen=True)
class CouplingRule:
    """Actuators that must not all travel far at once (e.g. a mouth corner pulled up and down together).

    The *share* of an actuator is |target - neutral| / |limit - neutral| towards the limit it moves to
    (0 at neutral, 1 at the limit). The rule holds when the shares of ``roles`` sum to at most
    ``max_sum_share``. The twin gate enforces it; the profile only states it.
    """

    roles: tuple[str, ...]
    max_sum_share: float
    note: str = ""


SERVO_MODELS: tuple[str, ...] = ("XL330-M288", "XL430-W250", "XM430-W350", "MX-28")
"""Servo models a head profile may name (the emulator and the calibration know these)."""

SERVO_MODEL_ALIASES: dict[str, str] = {"MX-28(2.0)": "MX-28"}
"""Other spellings a profile may use, as `servoface scan` and `servoface emulate` print them -> the name kept."""
