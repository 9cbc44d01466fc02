"""Skin binding: linear-blend weights from data rules (half-spaces, spheres) plus smoothing on the mesh.

A rule gives weight 1 where all its half-space conditions hold (``dot(p - point, normal) >= 0``) and,
if present, inside its sphere; each condition fades over ``falloff_mm``. Rules are evaluated at each
vertex nudged towards the centroid of its faces, so the two sides of a slit (the lips) land on their own
side of a rule plane although they share rest positions. Smoothing then diffuses the weights along mesh
edges only (never across a slit), which gives smooth cheeks while the lips stay apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim.heads.mesh_tools import smoothstep
from sim.rig import Vec3


@dataclass(frozen=True)
class HalfSpace:
    point_mm: Vec3
    normal: Vec3


@dataclass(frozen=True)
class BindRule:
    joint: str
    halfspaces: tuple[HalfSpace, ...] = ()
    sphere_centre_mm: Vec3 | None = None
    sphere_radius_mm: float = 0.0
    falloff_mm: float = 2.0
    weight: float = 1.0


def _sample_points(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray[np.float64]:
    cen = vertices[faces].mean(1)
    acc = np.zeros_like(vertices)
    cnt = np.zeros(len(vertices))
    for k in range(3):
        np.add.at(acc, faces[:, k], cen)
        np.add.at(cnt, faces[:, k], 1.0)
    cnt = np.maximum(cnt, 1.0)
    return 0.5 * vertices + 0.5 * acc / cnt[:, None]


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
        w *= smoothstep(0.5 + d / (2.0 * f))
    if rule.sphere_centre_mm is not None:
        d = np.linalg.norm(points - np.asarray(rule.sphere_centre_mm), axis=1)
        w *= smoothstep(0.5 + (rule.sphere_radius_mm - d) / (2.0 * f))
    return w


def bind_weights(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    rules: tuple[BindRule, ...],
    smooth_iterations: int,
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
    w = np.clip(w, 0.0, 1.0)
    total = w.sum(1)
    over = total > 1.0
    w[over] /= total[over, None]
    rest = 1.0 - w.sum(1)
    return tuple(joints), np.concatenate([rest[:, None], w], axis=1)
