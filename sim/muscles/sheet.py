"""Waters-style sheet muscle (parallel fibres, e.g. frontalis): Barker 2005 §4.4, muscle-models.md §1.2.

The sheet is a ribbon of fibres. Fibre u ∈ [0, 1] runs from lerp(attachment_mm, attachment_end_mm, u) to
lerp(insertion_mm, insertion_end_mm, u); the fibres may fan. Every point moves along its fibre towards the
attachment line:

    p      = signed projection of (x - fibre start) on the fibre direction f̂, I = fibre length
    a_par  = sin(p/I · π/2)                      for 0 <= p <= I          (0 on the attachment line)
           = cos((p - I)/(D_par - I) · π/2)      for I < p <= D_par        (corrected outer falloff)
    a_perp = 1 inside the ribbon's side edges; cos(e/width · π/2) at distance e beyond them (0 at width);
             the edges and the fibre u of a point are found at its level between the attachment edge
             and the insertion edge, so a fanned sheet widens or narrows smoothly
    a_dep  = 1 within depth_mm of the ribbon's plane; cos falloff to 0 at 2 · depth_mm (keeps the back of
             the head out)
    x'     = x - c · k · a_par · a_perp · a_dep · f̂,   k = max_contraction · I

With attachment_end = attachment and insertion_end = insertion shifted sideways the ribbon degenerates to
Barker's single-axis sheet (a_perp = cos(r_perp/D_perp · π/2) with D_perp = width_mm).
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
from servoface.sim.muscles.linear import DEFAULT_MAX_CONTRACTION

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def parallel_factor(
    p_mm: FloatArray | float, length_mm: FloatArray | float, reach_mm: FloatArray | float
) -> FloatArray:
    """a_par: 0 at p = 0 (and behind), 1 at p = I, 0 at p = D_par = reach_mm (continuous, monotone pieces)."""
    p = np.asarray(p_mm, dtype=np.float64)
    length = np.asarray(length_mm, dtype=np.float64)
    reach = np.asarray(reach_mm, dtype=np.float64)
    inner = np.sin(np.clip(p / length, 0.0, 1.0) * (math.pi / 2))
    outer = np.cos(np.clip((p - length) / (reach - length), 0.0, 1.0) * (math.pi / 2))
    out = np.where(p <= length, inner, outer)
    return np.where((p >= 0.0) & (p <= reach), out, 0.0)


def band_factor(excess_mm: FloatArray | float, band_mm: float) -> FloatArray:
    """1 at excess <= 0, cos(excess/band · π/2) for 0 < excess <= band, 0 beyond."""
    e = np.asarray(excess_mm, dtype=np.float64)
    return np.where(e <= band_mm, np.cos(np.clip(e / band_mm, 0.0, 1.0) * (math.pi / 2)), 0.0)


@dataclass(frozen=True)
class SheetMuscle:
    """A sheet muscle in the head frame (mm). ``width_mm`` is the side falloff band beyond the edge fibres."""

    name: str
    attachment_mm: Vec3
    attachment_end_mm: Vec3
    insertion_mm: Vec3
    insertion_end_mm: Vec3
    width_mm: float
    max_contraction: float = DEFAULT_MAX_CONTRACTION
    falloff_mm: float = 0.0  # D_par - I; 0 = half the mean fibre length
    depth_mm: float = 0.0  # 0 = half the mean fibre length
    type: Literal["sheet"] = "sheet"

    def __post_init__(self) -> None:
        where = f"muscles.{self.name}"
        mean = self.mean_length_mm
        if (
            min(
                distance(self.attachment_mm, self.insertion_mm),
                distance(self.attachment_end_mm, self.insertion_end_mm),
            )
            < 1e-6
        ):
            raise HeadProfileError(f"{where}: each fibre needs insertion != attachment")
        if self.width_mm <= 0.0:
            raise HeadProfileError(f"{where}.width_mm: expected a number > 0, got {self.width_mm}")
        if not 0.0 < self.max_contraction <= 1.0:
            raise HeadProfileError(f"{where}.max_contraction: expected a number in (0, 1], got {self.max_contraction}")
        if self.falloff_mm <= 0.0:
            object.__setattr__(self, "falloff_mm", 0.5 * mean)
        if self.depth_mm <= 0.0:
            object.__setattr__(self, "depth_mm", 0.5 * mean)
        _, t_hat, half_a, half_i = self._frame()
        if t_hat is not None and min(half_a, half_i) < 0.0:
            raise HeadProfileError(
                f"{where}: the fibres cross (attachment_end_mm and insertion_end_mm lie on opposite sides); "
                "swap insertion_mm and insertion_end_mm"
            )
        if t_hat is None:
            raise HeadProfileError(
                f"{where}: attachment_end_mm/insertion_end_mm give the sheet no sideways extent; use a linear muscle"
            )

    @property
    def mean_length_mm(self) -> float:
        return 0.5 * (
            distance(self.attachment_mm, self.insertion_mm) + distance(self.attachment_end_mm, self.insertion_end_mm)
        )

    def _frame(self) -> tuple[FloatArray, FloatArray | None, float, float]:
        """(mean fibre direction m̂, sideways unit t̂ or None, half-span of the attachment edge, of the
        insertion edge) of the ribbon, spans measured along t̂."""
        a0, a1 = np.asarray(self.attachment_mm), np.asarray(self.attachment_end_mm)
        i0, i1 = np.asarray(self.insertion_mm), np.asarray(self.insertion_end_mm)
        m = 0.5 * (i0 + i1) - 0.5 * (a0 + a1)
        m_hat = m / np.linalg.norm(m)
        side = 0.5 * ((a1 - a0) + (i1 - i0))
        side = side - (side @ m_hat) * m_hat
        span = float(np.linalg.norm(side))
        if span < 1e-6:
            return m_hat, None, 0.0, 0.0
        t_hat = side / span
        return m_hat, t_hat, 0.5 * float((a1 - a0) @ t_hat), 0.5 * float((i1 - i0) @ t_hat)

    @classmethod
    def from_mapping(cls, name: str, data: Mapping[str, Any], where: str | None = None) -> SheetMuscle:
        """Parse a ``[muscles.<name>]`` table with ``type = "sheet"``; errors carry the key path."""
        where = where or f"muscles.{name}"
        required = {"attachment_mm", "attachment_end_mm", "insertion_mm", "insertion_end_mm", "width_mm"}
        require_keys(data, where, required, {"max_contraction", "falloff_mm", "depth_mm"})
        pts = {key: vec3(data, key, where) for key in sorted(required - {"width_mm"})}
        width = number(data, "width_mm", where, low=0.0, low_open=True)
        lam = number(data, "max_contraction", where, default=DEFAULT_MAX_CONTRACTION, low=0.0, high=1.0, low_open=True)
        falloff = number(data, "falloff_mm", where, default=0.0, low=0.0)
        depth = number(data, "depth_mm", where, default=0.0, low=0.0)
        for a_key, i_key in (("attachment_mm", "insertion_mm"), ("attachment_end_mm", "insertion_end_mm")):
            if distance(pts[a_key], pts[i_key]) < 1e-6:
                raise HeadProfileError(f"{where}.{i_key}: expected a point away from {a_key} {pts[a_key]}")
        return cls(
            name,
            pts["attachment_mm"],
            pts["attachment_end_mm"],
            pts["insertion_mm"],
            pts["insertion_end_mm"],
            width,
            lam,
            falloff,
            depth,
        )

    def unit_field(self, rest_mm: FloatArray) -> tuple[IntArray, FloatArray]:
        """Displacement of every affected rest vertex at contraction c = 1: (indices (k,), (k, 3) mm)."""
        x = np.asarray(rest_mm, dtype=np.float64)
        a0, a1 = np.asarray(self.attachment_mm), np.asarray(self.attachment_end_mm)
        i0, i1 = np.asarray(self.insertion_mm), np.asarray(self.insertion_end_mm)
        m_hat, t_hat, half_a, half_i = self._frame()
        if t_hat is None:  # rejected in __post_init__; kept for the type checker
            raise HeadProfileError(f"muscles.{self.name}: the sheet has no sideways extent")
        n_hat = np.cross(m_hat, t_hat)
        mid_a, mid_i = 0.5 * (a0 + a1), 0.5 * (i0 + i1)
        # the level of each point between the attachment edge (0) and the insertion edge (1), and the
        # ribbon's centre and half-width at that level (a fanned sheet widens or narrows)
        level = np.clip(((x - mid_a) @ m_hat) / float((mid_i - mid_a) @ m_hat), 0.0, 1.0)
        rel = x - (mid_a[None, :] + level[:, None] * (mid_i - mid_a)[None, :])
        half = half_a + level * (half_i - half_a)
        s = rel @ t_hat
        across = np.abs(s) - half
        depth = np.abs(rel @ n_hat) - self.depth_mm
        a_perp = band_factor(across, self.width_mm) * band_factor(depth, self.depth_mm)
        cand = np.nonzero(a_perp > 0.0)[0]
        hc = half[cand]
        u = np.where(hc > 1e-9, np.clip((s[cand] + hc) / np.maximum(2 * hc, 1e-9), 0.0, 1.0), 0.5)
        start = a0 + u[:, None] * (a1 - a0)
        fibre = (i0 - a0) + u[:, None] * ((i1 - i0) - (a1 - a0))
        length = np.linalg.norm(fibre, axis=1)
        f_hat = fibre / length[:, None]
        p = np.einsum("ij,ij->i", x[cand] - start, f_hat)
        a_par = parallel_factor(p, length, length + self.falloff_mm)
        mag = self.max_contraction * length * a_par * a_perp[cand]
        nz = mag > 0.0
        return cand[nz].astype(np.int64), -(mag[nz, None] * f_hat[nz])
