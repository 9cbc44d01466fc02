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
