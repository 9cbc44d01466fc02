"""Sphincter muscle (e.g. orbicularis oris / oculi): Barker 2005 §4.4, corrected as in muscle-models.md §1.3.

An ellipsoid around ``centre_mm``: semi-axes (a, b) in the face plane along ``major_axis`` and the minor
axis, and a depth semi-axis ``c`` along ``normal`` (muscle-models.md: "in 3-D add a depth band so
back-of-head points are excluded"). With s = the components of v = x - centre along those axes:

    ρ = sqrt(s_maj²/a² + s_min²/b² + s_n²/c²)            (activation set: ρ <= 1)
    corrected falloff  g = 1 - ρ                          (1 at the centre, 0 on the ellipse)
    printed falloff    g = max(0, 1 - sqrt(a²s_maj² + b²s_min²)/(a·b))  (Barker's printed form, selectable)
    ring falloff       g = sin(π · ρ)                  ([project] 0 at the centre, peak on the ring ρ = 1/2, 0 on
                                                        the ellipse: a mouth whose corners come in without the
                                                        centre collapsing onto the axis)
    x' = x + min(c · k · g, |v_plane|) · (-v̂_plane),  k = max_contraction · a

The pull is towards the muscle's axis (through the centre, along the normal), never past it. It is linear
in c until a point would cross the centre; the cap keeps it there. Negative c (a DFACS counter AU) pushes
outwards, uncapped.
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
from servoface.sim.muscles.linear import DEFAULT_MAX_CONTRACTION

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Falloff = Literal["corrected", "printed", "ring"]
FALLOFFS = ("corrected", "printed", "ring")


def sphincter_falloff(
    s_maj: FloatArray | float,
    s_min: FloatArray | float,
    r_maj: float,
    r_min: float,
    form: Falloff = "corrected",
) -> FloatArray:
    """The in-plane falloff of muscle-models.md §1.3 (no clamping; the printed form goes negative)."""
    a = np.asarray(s_maj, dtype=np.float64)
    b = np.asarray(s_min, dtype=np.float64)
    if form == "printed":
        return 1.0 - np.sqrt(r_maj**2 * a**2 + r_min**2 * b**2) / (r_maj * r_min)
    return 1.0 - np.sqrt(a**2 / r_maj**2 + b**2 / r_min**2)


@dataclass(frozen=True)
class SphincterField:
    """A sphincter's precomputed field: per affected vertex a unit direction, a gain and a cap (mm)."""

    index: IntArray  # (k,)
    direction: FloatArray  # (k, 3) unit, towards the axis
    gain_mm: FloatArray  # (k,) = k · g: displacement per unit contraction
    cap_mm: FloatArray  # (k,) distance to the axis: never move past it

    def displacement(self, contraction: float) -> FloatArray:
        """(k, 3) displacement at contraction c (capped inwards, linear outwards)."""
        mag = contraction * self.gain_mm
        if contraction > 0.0:
            mag = np.minimum(mag, self.cap_mm)
        return mag[:, None] * self.direction


@dataclass(frozen=True)
class SphincterMuscle:
    """A sphincter in the head frame (mm): ``semi_axes_mm`` = (major, minor, depth)."""

    name: str
    centre_mm: Vec3
    semi_axes_mm: Vec3
    max_contraction: float = DEFAULT_MAX_CONTRACTION
    major_axis: Vec3 = (1.0, 0.0, 0.0)
    normal: Vec3 = (0.0, 0.0, 1.0)
    falloff: Falloff = "corrected"
    type: Literal["sphincter"] = "sphincter"

    def __post_init__(self) -> None:
        where = f"muscles.{self.name}"
        if min(self.semi_axes_mm) <= 0.0:
            raise HeadProfileError(f"{where}.semi_axes_mm: expected positive semi-axes, got {self.semi_axes_mm}")
        if not 0.0 < self.max_contraction <= 1.0:
            raise HeadProfileError(f"{where}.max_contraction: expected a number in (0, 1], got {self.max_contraction}")
        if abs(float(np.dot(self.major_axis, self.normal))) > 0.99:
            raise HeadProfileError(f"{where}.major_axis: expected a direction not parallel to normal {self.normal}")
        if self.falloff not in FALLOFFS:
            raise HeadProfileError(f"{where}.falloff: expected one of {list(FALLOFFS)}, got {self.falloff!r}")

    @property
    def gain_mm(self) -> float:
        """k = max_contraction · semi-major axis: the pull at the centre at full contraction (uncapped)."""
        return self.max_contraction * self.semi_axes_mm[0]

    @classmethod
    def from_mapping(cls, name: str, data: Mapping[str, Any], where: str | None = None) -> SphincterMuscle:
        """Parse a ``[muscles.<name>]`` table with ``type = "sphincter"``.

        ``semi_axes_mm`` = [major, minor] or [major, minor, depth] (depth defaults to the major axis).
        Optional: ``major_axis`` (default [1, 0, 0]), ``normal`` (default [0, 0, 1]), ``falloff``.
        """
        where = where or f"muscles.{name}"
        require_keys(data, where, {"centre_mm", "semi_axes_mm"}, {"max_contraction", "major_axis", "normal", "falloff"})
        centre = vec3(data, "centre_mm", where)
        axes = data["semi_axes_mm"]
        ok = isinstance(axes, list | tuple) and len(axes) in (2, 3)
        ok = ok and all(
            not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v) and v > 0 for v in axes
        )
        if not ok:
            raise HeadProfileError(f"{where}.semi_axes_mm: expected 2 or 3 positive finite numbers (mm), got {axes!r}")
        semi = (
            float(axes[0]),
            float(axes[1]),
            float(axes[2]) if len(axes) == 3 else float(max(axes[0], axes[1])),
        )
        lam = number(data, "max_contraction", where, default=DEFAULT_MAX_CONTRACTION, low=0.0, high=1.0, low_open=True)
        major = unit3(data, "major_axis", where, (1.0, 0.0, 0.0))
        normal = unit3(data, "normal", where, (0.0, 0.0, 1.0))
        form = data.get("falloff", "corrected")
        if form not in FALLOFFS:
            raise HeadProfileError(f"{where}.falloff: expected one of {list(FALLOFFS)}, got {form!r}")
        if abs(float(np.dot(major, normal))) > 0.99:
            raise HeadProfileError(f"{where}.major_axis: expected a direction not parallel to normal {normal}")
        return cls(name, centre, semi, lam, major, normal, form)

    def axes(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Orthonormal (major, minor, normal) unit vectors."""
        n = np.asarray(self.normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        e1 = np.asarray(self.major_axis, dtype=np.float64)
        e1 = e1 - (e1 @ n) * n
        e1 = e1 / np.linalg.norm(e1)
        return e1, np.cross(n, e1), n

    def field(self, rest_mm: FloatArray) -> SphincterField:
        """Precompute the field over the rest vertices (n, 3)."""
        e1, e2, n = self.axes()
        v = np.asarray(rest_mm, dtype=np.float64) - np.asarray(self.centre_mm)
        s1, s2, s3 = v @ e1, v @ e2, v @ n
        ra, rb, rc = self.semi_axes_mm
        rho = np.sqrt((s1 / ra) ** 2 + (s2 / rb) ** 2 + (s3 / rc) ** 2)
        inside = np.nonzero(rho < 1.0)[0]
        if self.falloff == "printed":
            g = np.maximum(sphincter_falloff(s1[inside], s2[inside], ra, rb, "printed"), 0.0) * (
                1.0 - np.abs(s3[inside]) / rc
            )
        elif self.falloff == "ring":
            g = np.sin(np.pi * rho[inside])
        else:
            g = 1.0 - rho[inside]
        planar = s1[inside, None] * e1 + s2[inside, None] * e2
        dist = np.linalg.norm(planar, axis=1)
        keep = (dist > 1e-9) & (g > 0.0)
        idx = inside[keep]
        direction = -planar[keep] / dist[keep, None]
        return SphincterField(idx.astype(np.int64), direction, self.gain_mm * g[keep], dist[keep])
