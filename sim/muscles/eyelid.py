"""Eyelid "muscle" for lid skin (Barker 2005 §4.4, reconstructed in muscle-models.md §1.4).

Skin points of a lid region turn about a horizontal axis through the eyeball centre ``c`` by the angle of
the lid joint (``joint``), weighted by a falloff so the lid skin stays attached to the brow/cheek skin;
then any point that would sit inside the eyeball shell is pushed out to radius r + ε:

    w  = R(axis, weight · angle) · (x - c)
    x' = c + max(|w|, r + ε) · ŵ             (|w| = |x - c|: a point outside the eyeball stays outside)

The activation set is the rest vertices within ``reach_mm`` of ``c`` on the lid's side of the axis
(above it for ``part = "upper"``, below for ``"lower"``);
weight = cos(π/2 · clip((|v| - r - ε)/(reach - r - ε)))
so the margin turns fully and the region's outer edge not at all. Unlike the vector muscles this is not
linear in the angle: the face model evaluates it per frame on its few vertices.

Use it only for skin that is NOT skinned to the lid joint by the rig weights (else the lid turns twice).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from servoface.sim.errors import HeadProfileError
from servoface.sim.muscles.fields import Vec3, number, require_keys, unit3, vec3

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def rotation_matrix(axis: FloatArray, angle_rad: FloatArray) -> FloatArray:
    """Rodrigues rotation matrices, (k, 3, 3), for a unit axis (3,) and k angles."""
    ang = np.atleast_1d(np.asarray(angle_rad, dtype=np.float64))
    x, y, z = axis
    k_mat = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    s, c = np.sin(ang)[:, None, None], np.cos(ang)[:, None, None]
    out = np.eye(3)[None] + s * k_mat[None] + (1.0 - c) * (k_mat @ k_mat)[None]
    return np.asarray(out, dtype=np.float64)


@dataclass(frozen=True)
class EyelidField:
    """Precomputed lid region: vertex indices, their offsets from c (k, 3) and turning weights (k,)."""

    index: IntArray
    rel_mm: FloatArray
    weight: FloatArray
    axis: FloatArray
    shell_mm: float

    def displacement(self, angle_deg: float) -> FloatArray:
        """(k, 3) offsets of the region's vertices from rest for a lid angle (deg, + = closing)."""
        if self.index.size == 0 or angle_deg == 0.0:
            return np.zeros((self.index.size, 3))
        rot = rotation_matrix(self.axis, np.radians(angle_deg) * self.weight)
        w = np.einsum("kij,kj->ki", rot, self.rel_mm)
        norm = np.linalg.norm(w, axis=1)
        scale = np.maximum(norm, self.shell_mm) / np.maximum(norm, 1e-12)
        return np.asarray(w * scale[:, None] - self.rel_mm, dtype=np.float64)


@dataclass(frozen=True)
class EyelidMuscle:
    """Lid skin turned by the lid joint. ``axis`` is the turning axis; + angle turns the lid closed."""

    name: str
    centre_mm: Vec3
    radius_mm: float
    joint: str
    part: Literal["upper", "lower"] = "upper"
    reach_mm: float = 0.0  # 0 = 1.6 x radius
    thickness_mm: float = 1.0
    axis: Vec3 = (
        0.0,
        0.0,
        0.0,
    )  # 0 = (1, 0, 0) for the upper lid (+ closes), (-1, 0, 0) for the lower (+ raises)
    type: Literal["eyelid"] = "eyelid"

    def __post_init__(self) -> None:
        where = f"muscles.{self.name}"
        if self.radius_mm <= 0.0:
            raise HeadProfileError(f"{where}.radius_mm: expected a number > 0, got {self.radius_mm}")
        if self.reach_mm <= 0.0:
            object.__setattr__(self, "reach_mm", 1.6 * self.radius_mm)
        if self.reach_mm <= self.radius_mm + self.thickness_mm:
            raise HeadProfileError(f"{where}.reach_mm: expected > radius_mm + thickness_mm, got {self.reach_mm}")
        if self.part not in ("upper", "lower"):
            raise HeadProfileError(f"{where}.part: expected 'upper' or 'lower', got {self.part!r}")
        if self.axis == (0.0, 0.0, 0.0):
            object.__setattr__(self, "axis", (1.0, 0.0, 0.0) if self.part == "upper" else (-1.0, 0.0, 0.0))

    @classmethod
    def from_mapping(cls, name: str, data: Mapping[str, Any], where: str | None = None) -> EyelidMuscle:
        """Parse ``type = "eyelid"``: ``centre_mm``, ``radius_mm``, ``joint``; optional ``part``,
        ``reach_mm``, ``thickness_mm``, ``axis``."""
        where = where or f"muscles.{name}"
        require_keys(data, where, {"centre_mm", "radius_mm", "joint"}, {"part", "reach_mm", "thickness_mm", "axis"})
        centre = vec3(data, "centre_mm", where)
        radius = number(data, "radius_mm", where, low=0.0, low_open=True)
        joint = data["joint"]
        if not isinstance(joint, str) or not joint:
            raise HeadProfileError(f"{where}.joint: expected a joint name, got {joint!r}")
        part = data.get("part", "upper")
        if part not in ("upper", "lower"):
            raise HeadProfileError(f"{where}.part: expected 'upper' or 'lower', got {part!r}")
        thickness = number(data, "thickness_mm", where, default=1.0, low=0.0)
        reach = number(data, "reach_mm", where, default=1.6 * radius, low=radius + thickness, low_open=True)
        axis = unit3(data, "axis", where, (1.0, 0.0, 0.0) if part == "upper" else (-1.0, 0.0, 0.0))
        return cls(name, centre, radius, joint, part, reach, thickness, axis)

    def field(self, rest_mm: FloatArray) -> EyelidField:
        """Precompute the region over the rest vertices (n, 3)."""
        axis = np.asarray(self.axis, dtype=np.float64)
        axis = axis / np.linalg.norm(axis)
        rel = np.asarray(rest_mm, dtype=np.float64) - np.asarray(self.centre_mm)
        dist = np.linalg.norm(rel, axis=1)
        up = np.array([0.0, 1.0, 0.0]) - axis[1] * axis  # "above the axis": head +y, made normal to the axis
        if np.linalg.norm(up) < 1e-9:
            up = np.array([0.0, 0.0, 1.0])
        side = rel @ (up / np.linalg.norm(up))
        on_side = side > 0.0 if self.part == "upper" else side < 0.0
        idx = np.nonzero(on_side & (dist < self.reach_mm))[0]
        shell = self.radius_mm + self.thickness_mm
        t = np.clip((dist[idx] - shell) / (self.reach_mm - shell), 0.0, 1.0)
        weight = np.cos(t * (math.pi / 2))
        return EyelidField(idx.astype(np.int64), rel[idx], weight, axis, shell)
