"""The twin's skin: pose it cheaply (rest + B @ pulls, then linear-blend skinning) and measure strain.

``B`` is the anchor-pull deformation basis (3n, n_anchors), precomputed once from the face model (or the
built-in falloff model when no face model is given), so one frame costs two small matrix products.
Strain = edge length / rest length on a precomputed edge list; a triangle *flips* when its posed normal
points against its rest normal carried by the skinning rotation at that triangle.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim.gate.errors import GateConfigError
from sim.gate.fk import JointTree
from sim.gate.verdict import Finding

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StrainLimits:
    """Largest allowed edge stretch and smallest allowed compression (ratios to rest length)."""

    max_stretch: float = 1.6
    min_compression: float = 0.5
    max_flipped: int = 0


def falloff_offsets(skin: Any, anchors: Sequence[Any], pulls_mm: Mapping[str, float]) -> FloatArray:
    """Fallback skin offsets from anchor pulls: each anchor drags the skin near it along its line with a
    raised-cosine falloff over ``radius_mm`` (used when no face model is given). (n, 3) mm."""
    v = np.asarray(skin.vertices_mm, dtype=np.float64)
    out = np.zeros_like(v)
    for a in anchors:
        pull = float(pulls_mm.get(a.role, 0.0))
        if pull == 0.0:
            continue
        d = np.linalg.norm(v - v[a.vertex], axis=1) / max(a.radius_mm, 1e-9)
        w = np.where(d < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(d, 1.0))), 0.0)
        out += pull * w[:, None] * np.asarray(a.line, dtype=np.float64)[None, :]
    return out


def pull_basis(
    offsets: Callable[[Mapping[str, float]], FloatArray],
    roles: Sequence[str],
    neutral_mm: Sequence[float],
    unit_mm: Sequence[float],
) -> tuple[FloatArray, FloatArray, float]:
    """(base (n, 3), B (3n, k), nonlinearity) with offsets(pulls) ~ base + B @ (pulls - neutral).

    Columns are finite differences of ``unit_mm`` per anchor; ``nonlinearity`` is the largest error (mm)
    of the linear model at one mixed test point, so the caller can refuse a face model that is not linear.
    """
    neutral = dict(zip(roles, neutral_mm, strict=True))
    base = np.asarray(offsets(neutral), dtype=np.float64)
    cols = []
    for role, unit in zip(roles, unit_mm, strict=True):
        probe = dict(neutral)
        probe[role] = neutral[role] + unit
        cols.append(((np.asarray(offsets(probe)) - base) / unit).reshape(-1))
    basis = np.stack(cols, axis=1) if cols else np.zeros((base.size, 0))
    mix = {
        r: neutral[r] + 0.5 * u * (1 if i % 2 else -1)
        for i, (r, u) in enumerate(zip(roles, unit_mm, strict=True))
    }
    pred = base.reshape(-1) + basis @ np.array([mix[r] - neutral[r] for r in roles])
    err = float(np.max(np.abs(np.asarray(offsets(mix)).reshape(-1) - pred))) if roles else 0.0
    return base, basis, err


class SkinTwin:
    """Vectorised skin posing and strain for one head."""

    def __init__(self, skin: Any, tree: JointTree, base_offset: FloatArray, basis: FloatArray) -> None:
        self.rest = np.asarray(skin.vertices_mm, dtype=np.float64)
        self.faces = np.asarray(skin.faces, dtype=np.int64)
        n = self.rest.shape[0]
        if basis.shape[0] != 3 * n or base_offset.shape != (n, 3):
            raise GateConfigError(
                f"skin basis shapes {basis.shape}/{base_offset.shape} do not fit {n} vertices"
            )
        self.base = self.rest + base_offset
        self.basis = basis
        weights = np.asarray(skin.weights, dtype=np.float64)
        # columns: 0 = head base, j + 1 = skin.joint_names[j]  ->  slot order of JointTree + base last
        slot = [len(tree.names)] + [tree.index[name] for name in skin.joint_names]
        self.weights = np.zeros((n, len(tree.names) + 1))
        np.add.at(self.weights.T, np.array(slot), weights.T)
        used = np.nonzero(self.weights.any(axis=0))[0]
        self._used = used
        self._w_used = self.weights[:, used]
        e = np.sort(
            np.concatenate([self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]]), axis=1
        )
        self.edges = np.unique(e, axis=0)
        self.rest_len = np.linalg.norm(self.rest[self.edges[:, 0]] - self.rest[self.edges[:, 1]], axis=1)
        if np.any(self.rest_len <= 0):
            raise GateConfigError("skin has zero-length edges at rest")
        self.rest_normal = self._normals(self.rest)
        self._split_active()

    def _split_active(self) -> None:
        """Edges and faces whose shape can change (touched by a pull, blended between joints, or spanning
        two joints) are measured per frame; the rest keep their neutral values, computed once here."""
        w = self.weights
        one_joint = (w > 0).sum(axis=1) == 1
        pulled = np.abs(self.basis).reshape(-1, 3, self.basis.shape[1]).sum(axis=(1, 2)) > 0
        joint_of = np.where(one_joint, np.argmax(w, axis=1), -1)
        soft = ~one_joint | pulled
        e0, e1 = self.edges[:, 0], self.edges[:, 1]
        act_e = soft[e0] | soft[e1] | (joint_of[e0] != joint_of[e1])
        f = self.faces
        act_f = (
            soft[f].any(axis=1)
            | (joint_of[f[:, 0]] != joint_of[f[:, 1]])
            | (joint_of[f[:, 0]] != joint_of[f[:, 2]])
        )
        base_ratio = np.linalg.norm(self.base[e0] - self.base[e1], axis=1) / self.rest_len
        fixed = ~act_e
        self._const_max = float(base_ratio[fixed].max()) if fixed.any() else 0.0
        self._const_min = float(base_ratio[fixed].min()) if fixed.any() else np.inf
        base_n = self._normals(self.base)
        self._const_flips = int((np.einsum("fi,fi->f", base_n, self.rest_normal)[~act_f] <= 0.0).sum())
        verts = np.unique(np.concatenate([self.edges[act_e].ravel(), f[act_f].ravel()]))
        remap = np.full(len(self.rest), -1, dtype=np.int64)
        remap[verts] = np.arange(len(verts))
        self._v = verts
        self._edges = remap[self.edges[act_e]]
        self._rest_len = self.rest_len[act_e]
        self._faces = remap[f[act_f]]
        self._rest_normal = self.rest_normal[act_f]
        self._base = self.base[verts]
        self._basis = self.basis.reshape(-1, 3, self.basis.shape[1])[verts].reshape(-1, self.basis.shape[1])
        self._w = self._w_used[verts]
        self._face_w = self._w_used[f[act_f]].mean(axis=1)
        self.n_active_edges = int(act_e.sum())
        self.n_active_faces = int(act_f.sum())

    def _normals(self, v: FloatArray) -> FloatArray:
        t = v[..., self.faces, :]
        return np.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :])

    def _mats(self, world: FloatArray) -> FloatArray:
        """(..., u, 12) the used joints' (3, 4) transforms, head base last."""
        lead = world.shape[:-3]
        eye = np.broadcast_to(np.eye(4), (*lead, 1, 4, 4))
        mats = np.concatenate([world, eye], axis=-3)[..., self._used, :3, :]
        return mats.reshape(*lead, len(self._used), 12)

    def posed(self, world: FloatArray, pulls: FloatArray) -> FloatArray:
        """(..., n, 3) every posed skin vertex; ``pulls`` (..., k) mm from neutral."""
        v = self.base + (pulls @ self.basis.T).reshape(*pulls.shape[:-1], -1, 3)
        m = (self._w_used @ self._mats(world)).reshape(*v.shape[:-1], 3, 4)
        return np.einsum("...nij,...nj->...ni", m[..., :3], v) + m[..., 3]

    def measure(
        self, world: FloatArray, pulls: FloatArray
    ) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """(max stretch (...,), min compression (...,), flipped triangle count (...,))."""
        mats = self._mats(world)
        v = self._base + (pulls @ self._basis.T).reshape(*pulls.shape[:-1], -1, 3)
        m = (self._w @ mats).reshape(*v.shape[:-1], 3, 4)
        v = np.einsum("...nij,...nj->...ni", m[..., :3], v) + m[..., 3]
        d = v[..., self._edges[:, 0], :] - v[..., self._edges[:, 1], :]
        ratio = np.sqrt(np.einsum("...ei,...ei->...e", d, d)) / self._rest_len
        rot = (self._face_w @ mats).reshape(*v.shape[:-2], -1, 3, 4)[..., :3]
        expect = np.einsum("...fij,fj->...fi", rot, self._rest_normal)
        p0 = v[..., self._faces[:, 0], :]
        u = v[..., self._faces[:, 1], :] - p0
        w = v[..., self._faces[:, 2], :] - p0
        ux, uy, uz = u[..., 0], u[..., 1], u[..., 2]
        wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
        dot = (uy * wz - uz * wy) * expect[..., 0] + (uz * wx - ux * wz) * expect[..., 1]
        dot += (ux * wy - uy * wx) * expect[..., 2]
        flipped = dot <= 0.0
        stretch = np.maximum(ratio.max(axis=-1, initial=0.0), self._const_max)
        comp = np.minimum(ratio.min(axis=-1, initial=np.inf), self._const_min)
        return stretch, comp, flipped.sum(axis=-1) + self._const_flips


def strain_findings(stretch: float, compression: float, flipped: int, limits: StrainLimits) -> list[Finding]:
    out = []
    if stretch > limits.max_stretch:
        out.append(
            Finding(
                "strain",
                f"skin edge stretched to {stretch:.2f}x rest (limit {limits.max_stretch:.2f}x)",
                value=stretch,
                limit=limits.max_stretch,
                unit="ratio",
            )
        )
    if compression < limits.min_compression:
        out.append(
            Finding(
                "strain",
                f"skin edge compressed to {compression:.2f}x rest (limit {limits.min_compression:.2f}x)",
                value=compression,
                limit=limits.min_compression,
                unit="ratio",
            )
        )
    if flipped > limits.max_flipped:
        out.append(
            Finding(
                "flip",
                f"{flipped} skin triangle(s) flipped against their rest normal (limit {limits.max_flipped})",
                value=float(flipped),
                limit=float(limits.max_flipped),
                unit="triangles",
            )
        )
    return out
