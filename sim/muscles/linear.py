"""Waters-style linear muscle (Barker 2005 §4.4; corrected forms of muscle-models.md §1.1).

A linear muscle pulls skin inside a cone around its line of action towards the fixed attachment ``ap``:

    v = x - ap,  φ = angle(v, m) with m = ip - ap,  I = |m|
    angular factor a = cos(φ/θ · π/2)                      (1 on the axis, 0 at the cone edge θ)
    radial factor  r = cos((rs - |v|)/rs · π/2)            for |v| <= rs   (0 at ap, 1 at rs)
                     = cos((|v| - rs)/(rf - rs) · π/2)     for rs < |v| <= rf  (1 at rs, 0 at rf)
    x' = x - c · k · a · r · v/|v|,   k = max_contraction · I

Every displacement is taken from the REST position, so the field per unit contraction is fixed and a frame
is ``x_rest + Σ c_m W_m`` (order-independent, linear in c).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from servoface.sim.errors import HeadProfileError
from servoface.sim.muscles.fields import Vec3, distance, number, require_keys, vec3

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

DEFAULT_MAX_CONTRACTION = 0.25  # Barker: "typically 25 % of neutral length"


def angular_factor(phi_rad: FloatArray | float, zone_rad: float) -> FloatArray:
    """a = cos(φ/θ · π/2) inside the cone, 0 outside: 1 on the axis, 0 at (and beyond) the edge."""
    phi = np.asarray(phi_rad, dtype=np.float64)
    out = np.cos(np.clip(phi / zone_rad, 0.0, 1.0) * (math.pi / 2))
    return np.where(phi <= zone_rad, out, 0.0)


def radial_factor(dist_mm: FloatArray | float, rs_mm: float, rf_mm: float) -> FloatArray:
    """Waters' radial falloff: 0 at the attachment, 1 at rs, 0 at rf and beyond."""
    d = np.asarray(dist_mm, dtype=np.float64)
    inner = np.cos((rs_mm - np.clip(d, 0.0, rs_mm)) / rs_mm * (math.pi / 2))
    outer = np.cos((np.clip(d, rs_mm, rf_mm) - rs_mm) / (rf_mm - rs_mm) * (math.pi / 2))
    out = np.where(d <= rs_mm, inner, outer)
    return np.where(d <= rf_mm, out, 0.0)


@dataclass(frozen=True)
class LinearMuscle:
    """A linear muscle in the head frame (mm). ``zone_deg`` is the half-angle θ of the cone of influence."""

    name: str
    attachment_mm: Vec3
    insertion_mm: Vec3
    zone_deg: float = 45.0
    rs_mm: float = 0.0  # 0 = the muscle length |ip - ap|
    rf_mm: float = 0.0  # 0 = 1.5 x rs
    max_contraction: float = DEFAULT_MAX_CONTRACTION
    type: Literal["linear"] = "linear"

    def __post_init__(self) -> None:
        length = self.length_mm
        where = f"muscles.{self.name}"
        if length < 1e-6:
            raise HeadProfileError(
                f"{where}: attachment_mm and insertion_mm must differ, both are {self.attachment_mm}"
            )
        if self.rs_mm <= 0.0:
            object.__setattr__(self, "rs_mm", length)
        if self.rf_mm <= 0.0:
            object.__setattr__(self, "rf_mm", 1.5 * self.rs_mm)
        if self.rf_mm <= self.rs_mm:
            raise HeadProfileError(f"{where}.rf_mm: expected rf_mm > rs_mm = {self.rs_mm}, got {self.rf_mm}")
        if not 0.0 < self.zone_deg < 180.0:
            raise HeadProfileError(f"{where}.zone_deg: expected a number in (0, 180), got {self.zone_deg}")
        if not 0.0 < self.max_contraction <= 1.0:
            raise HeadProfileError(f"{where}.max_contraction: expected a number in (0, 1], got {self.max_contraction}")

    @property
    def length_mm(self) -> float:
        return distance(self.attachment_mm, self.insertion_mm)

    @property
    def gain_mm(self) -> float:
        """k = max_contraction · |ip - ap|: the pull at full contraction where a = r = 1."""
        return self.max_contraction * self.length_mm

    @classmethod
    def from_mapping(cls, name: str, data: Mapping[str, Any], where: str | None = None) -> LinearMuscle:
        """Parse a ``[muscles.<name>]`` table with ``type = "linear"``; errors carry the key path."""
        where = where or f"muscles.{name}"
        require_keys(data, where, {"attachment_mm", "insertion_mm"}, {"zone_deg", "rs_mm", "rf_mm", "max_contraction"})
        attachment = vec3(data, "attachment_mm", where)
        insertion = vec3(data, "insertion_mm", where)
        if distance(attachment, insertion) < 1e-6:
            raise HeadProfileError(f"{where}.insertion_mm: expected a point away from attachment_mm {attachment}")
        zone = number(data, "zone_deg", where, default=45.0, low=0.0, high=179.0, low_open=True)
        rs = number(data, "rs_mm", where, default=distance(attachment, insertion), low=0.0, low_open=True)
        rf = number(data, "rf_mm", where, default=1.5 * rs, low=0.0, low_open=True)
        if rf <= rs:
            raise HeadProfileError(f"{where}.rf_mm: expected a number > rs_mm = {rs}, got {rf}")
        lam = number(data, "max_contraction", where, default=DEFAULT_MAX_CONTRACTION, low=0.0, high=1.0, low_open=True)
        return cls(name, attachment, insertion, zone, rs, rf, lam)

    def unit_field(self, rest_mm: FloatArray) -> tuple[IntArray, FloatArray]:
        """Displacement of every affected rest vertex at contraction c = 1.

        rest_mm: (n, 3) float. Returns (indices (k,) int, displacement (k, 3) float mm); other vertices stay.
        """
        ap = np.asarray(self.attachment_mm, dtype=np.float64)
        m = np.asarray(self.insertion_mm, dtype=np.float64) - ap
        v = np.asarray(rest_mm, dtype=np.float64) - ap
        d = np.linalg.norm(v, axis=1)
        near = np.nonzero((d <= self.rf_mm) & (d > 1e-9))[0]
        v, d = v[near], d[near]
        cos_phi = np.clip(v @ m / (d * self.length_mm), -1.0, 1.0)
        phi = np.arccos(cos_phi)
        zone = math.radians(self.zone_deg)
        keep = phi < zone
        near, v, d, phi = near[keep], v[keep], d[keep], phi[keep]
        mag = self.gain_mm * angular_factor(phi, zone) * radial_factor(d, self.rs_mm, self.rf_mm)
        disp = -(mag / d)[:, None] * v
        nz = mag > 0.0
        return near[nz].astype(np.int64), disp[nz]
