"""Pairs that provably never collide, so they need neither a TSS table nor an exact test.

Lids ride on the eyeball: both turn about the eye centre. When every joint that moves one part relative to
the other turns about an axis through one common point c, each part keeps its distances to c, so if one
part lies entirely inside a ball around c and the other entirely outside it, no pose can make them meet.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree

FloatArray = NDArray[np.float64]


def common_centre(tree: JointTree, joints: list[int], tol_mm: float = 1e-6) -> FloatArray | None:
    """The point every listed joint axis passes through, or None."""
    if not joints:
        return None
    p = tree.pivot_mm[joints]
    a = tree.axis[joints]
    # least squares: sum_j (I - a a^T)(c - p_j) = 0
    m = np.zeros((3, 3))
    rhs = np.zeros(3)
    for pj, aj in zip(p, a, strict=True):
        proj = np.eye(3) - np.outer(aj, aj)
        m += proj
        rhs += proj @ pj
    c = np.linalg.lstsq(m, rhs, rcond=None)[0]
    d = np.linalg.norm(np.cross(c - p, a), axis=1)
    return np.asarray(c, dtype=np.float64) if np.all(d <= tol_mm) else None


def point_triangle_distance(c: FloatArray, tri: FloatArray) -> FloatArray:
    """Exact distance from point c (3,) to each triangle (m, 3, 3) (Ericson, RTCD 5.1.5)."""
    a, b, cc = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, cc - a, c - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = c - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = c - cc
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        closest = a + ab * v[:, None] + ac * w[:, None]  # interior
        # vertex regions
        closest = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, closest)
        closest = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, closest)
        closest = np.where(((d6 >= 0) & (d5 <= d6))[:, None], cc, closest)
        # edge regions
        t_ab = np.where(d1 - d3 != 0, d1 / (d1 - d3), 0.0)
        e_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        closest = np.where(e_ab[:, None], a + ab * t_ab[:, None], closest)
        t_ac = np.where(d2 - d6 != 0, d2 / (d2 - d6), 0.0)
        e_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        closest = np.where(e_ac[:, None], a + ac * t_ac[:, None], closest)
        t_bc = np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) / ((d4 - d3) + (d5 - d6)), 0.0)
        e_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
        closest = np.where(e_bc[:, None], b + (cc - b) * t_bc[:, None], closest)
    # regions are exclusive except on boundaries, where the candidates coincide
    return np.asarray(np.linalg.norm(closest - c, axis=1))


def radial_range_mm(mesh: Any, c: FloatArray) -> tuple[float, float]:
    """(nearest, farthest) distance from c to the mesh surface (exact)."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    tri = v[np.asarray(mesh.faces)]
    return float(point_triangle_distance(c, tri).min()), float(np.linalg.norm(v - c, axis=1).max())


def concentric_separation(
    tree: JointTree, joint_a: str | None, joint_b: str | None, mesh_a: Any, mesh_b: Any, rel: list[int]
) -> str | None:
    """A reason string when the pair provably never collides (see module docstring), else None."""
    c = common_centre(tree, rel)
    if c is None:
        return None
    a_lo, a_hi = radial_range_mm(mesh_a, c)
    b_lo, b_hi = radial_range_mm(mesh_b, c)
    if a_hi < b_lo or b_hi < a_lo:
        inner, outer = (a_hi, b_lo) if a_hi < b_lo else (b_hi, a_lo)
        return (
            f"turn about a common centre {np.round(c, 2).tolist()} mm with separated shells "
            f"(inner <= {inner:.2f} mm < outer >= {outer:.2f} mm): cannot collide"
        )
    return None
