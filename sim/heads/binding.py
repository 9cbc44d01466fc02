"""Skin binding: linear-blend weights from data rules (half-spaces, spheres) plus smoothing on the mesh.

A rule gives weight 1 where all its half-space conditions hold (``dot(p - point, normal) >= 0``) and,
if present, inside its sphere; each condition fades over ``falloff_mm``. Rules are evaluated at each
vertex; the two copies of a slit vertex (the lips share rest positions) are first nudged 2 mm towards
their own faces, so each lands on its own side of a rule plane. Smoothing then diffuses the weights along mesh
edges only (never across a slit), which gives smooth cheeks while the lips stay apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from servoface.sim.heads.mesh_tools import smoothstep
from servoface.sim.rig import Vec3


@dataclass(frozen=True)
class HalfSpace:
    point_mm: Vec3
    normal: Vec3
    falloff_mm: float | None = None  # None: the rule's falloff


@dataclass(frozen=True)
class BindRule:
    joint: str
    halfspaces: tuple[HalfSpace, ...] = ()
    sphere_centre_mm: Vec3 | None = None
    sphere_radius_mm: float = 0.0
    falloff_mm: float = 2.0
    weight: float = 1.0


SLIT_NUDGE_MM = 2.0


def _duplicated(vertices: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Vertices that share their rest position with another vertex (the two sides of a slit)."""
    _, inverse, counts = np.unique(np.round(vertices, 6), axis=0, return_inverse=True, return_counts=True)
    return np.asarray(counts[inverse.ravel()] > 1, dtype=bool)


def _sample_points(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray[np.float64]:
    """Where the rules are evaluated: each vertex, except that the copies on a slit are moved
    ``SLIT_NUDGE_MM`` towards their own faces (so each lip lands on its own side of the lip plane)."""
    cen = vertices[faces].mean(1)
    acc = np.zeros_like(vertices)
    cnt = np.zeros(len(vertices))
    for k in range(3):
        np.add.at(acc, faces[:, k], cen)
        np.add.at(cnt, faces[:, k], 1.0)
    direction = acc / np.maximum(cnt, 1.0)[:, None] - vertices
    norm = np.linalg.norm(direction, axis=1, keepdims=True)
    step = np.where(norm > 1e-12, direction / np.maximum(norm, 1e-12), 0.0) * SLIT_NUDGE_MM
    return np.asarray(vertices + step * _duplicated(vertices)[:, None], dtype=np.float64)


def _neighbour_mean_matrix(n: int, faces: NDArray[np.int64]) -> object:
    import scipy.sparse as sp

    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.concatenate([e, e[:, ::-1]])
    a = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    a.data[:] = 1.0
    deg = np.asarray(a.sum(1)).ravel()
    deg[deg == 0] = 1.0
    return sp.diags(1.0 / deg) @ a


def rule_weight(rule: BindRule, points: NDArray[np.float64]) -> NDArray[np.float64]:
    w = np.full(len(points), float(rule.weight))
    f = max(rule.falloff_mm, 1e-6)
    for hs in rule.halfspaces:
        nrm = np.asarray(hs.normal, dtype=np.float64)
        nrm = nrm / np.linalg.norm(nrm)
        d = (points - np.asarray(hs.point_mm)) @ nrm
        fh = f if hs.falloff_mm is None else max(hs.falloff_mm, 1e-6)
        w *= smoothstep(0.5 + d / (2.0 * fh))
    if rule.sphere_centre_mm is not None:
        d = np.linalg.norm(points - np.asarray(rule.sphere_centre_mm), axis=1)
        w *= smoothstep(0.5 + (rule.sphere_radius_mm - d) / (2.0 * f))
    return w


def slit_ends(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray[np.int64]:
    """Vertices where a slit (two boundary rows sharing rest positions, e.g. the lips) ends: the corners."""
    dup = _duplicated(vertices)
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, n = np.unique(e, axis=0, return_counts=True)
    b = uniq[n == 1]
    ends = np.concatenate([b[dup[b[:, 1]] & ~dup[b[:, 0]], 0], b[dup[b[:, 0]] & ~dup[b[:, 1]], 1]])
    return np.asarray(np.unique(ends), dtype=np.int64)


def blend_slit_corners(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], w: NDArray[np.float64], radius_mm: float
) -> NDArray[np.float64]:
    """Within ``radius_mm`` of a slit's end, pull the weights towards the corner's own weight (smoothly),
    so the slit opens like a mouth (a rounded diamond) instead of tearing at its corners."""
    ends = slit_ends(vertices, faces)
    if radius_mm <= 0 or len(ends) == 0:
        return w
    d = np.linalg.norm(vertices[:, None, :] - vertices[ends][None, :, :], axis=2)
    nearest = np.argmin(d, axis=1)
    ramp = smoothstep(d[np.arange(len(vertices)), nearest] / radius_mm)[:, None]
    corner = w[ends[nearest]]
    return np.asarray(corner + (w - corner) * ramp, dtype=np.float64)


def bind_weights(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    rules: tuple[BindRule, ...],
    smooth_iterations: int,
    slit_corner_blend_mm: float = 0.0,
) -> tuple[tuple[str, ...], NDArray[np.float64]]:
    """(joint names, weights (n, K + 1)) with column 0 = the skin's own joint (the rest of each row).

    The caller maps column 0 to the skin joint; rows sum to 1.
    """
    joints: list[str] = []
    for r in rules:
        if r.joint not in joints:
            joints.append(r.joint)
    n = len(vertices)
    pts = _sample_points(vertices, faces)
    w = np.zeros((n, len(joints)))
    for r in rules:
        k = joints.index(r.joint)
        w[:, k] = np.maximum(w[:, k], rule_weight(r, pts))
    if smooth_iterations > 0 and joints:
        m = _neighbour_mean_matrix(n, faces)
        for _ in range(smooth_iterations):
            w = 0.5 * w + 0.5 * (m @ w)  # type: ignore[operator]
    if slit_corner_blend_mm > 0 and joints:
        w = blend_slit_corners(vertices, faces, w, slit_corner_blend_mm)
    w = np.clip(w, 0.0, 1.0)
    w[w < 1e-4] = 0.0  # keep the weights sparse: diffusion leaves traces everywhere
    total = w.sum(1)
    over = total > 1.0
    w[over] /= total[over, None]
    rest = 1.0 - w.sum(1)
    return tuple(joints), np.concatenate([rest[:, None], w], axis=1)
