"""The twin's skin: pose it (rest + offsets from the anchor pulls, then linear-blend skinning) and
measure strain, only where the skin can change shape.

Strain = edge length / rest length on a precomputed edge list; a triangle *flips* when its posed normal
points against its rest normal carried by the skinning rotation at that triangle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.verdict import Finding

FloatArray = NDArray[np.float64]
_Measured = tuple[float, float, int, NDArray[np.bool_]]  # `SkinTwin.measure_one_faces`' answer


@dataclass(frozen=True)
class StrainLimits:
    """Largest allowed edge stretch and smallest allowed compression (ratios to rest length).

    Defaults suit a cast silicone skin (Ecoflex-class elongation at break is several times its length;
    3x is a working limit) and let the built-in expressions through, whose apexes stretch up to ~2.6x
    and bunch brow skin to ~0.16x. A profile or the caller narrows them for a stiffer skin."""

    max_stretch: float = 3.0
    min_compression: float = 0.1
    max_flipped: int = 0


class SkinTwin:
    """Vectorised skin posing and strain for one head."""

    def __init__(self, skin: Any, tree: JointTree, movable: NDArray[np.bool_]) -> None:
        """``movable`` (n,) marks the vertices the anchor pulls can move (see `skin_source`)."""
        self.rest = np.asarray(skin.vertices_mm, dtype=np.float64)
        self.faces = np.asarray(skin.faces, dtype=np.int64)
        n = self.rest.shape[0]
        if movable.shape != (n,):
            raise GateConfigError(f"movable mask shape {movable.shape} does not fit {n} skin vertices")
        self.movable = movable
        weights = np.asarray(skin.weights, dtype=np.float64)
        # columns: 0 = head base, j + 1 = skin.joint_names[j]  ->  slot order of JointTree + base last
        slot = [len(tree.names)] + [tree.index[name] for name in skin.joint_names]
        self.weights = np.zeros((n, len(tree.names) + 1))
        np.add.at(self.weights.T, np.array(slot), weights.T)
        used = np.nonzero(self.weights.any(axis=0))[0]
        self._used = used
        self._no_base = bool(len(used)) and int(used[-1]) < len(tree.names)  # the base slot (last) not used
        self._w_used = self.weights[:, used]
        e = np.sort(np.concatenate([self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]]), axis=1)
        self.edges = np.unique(e, axis=0)
        self.rest_len = np.linalg.norm(self.rest[self.edges[:, 0]] - self.rest[self.edges[:, 1]], axis=1)
        if np.any(self.rest_len <= 0):
            raise GateConfigError("skin has zero-length edges at rest")
        self.rest_normal = self._normals(self.rest)
        self._split_active()

    def _split_active(self) -> None:
        """Edges and faces whose shape can change (touched by a pull, blended between joints, or spanning
        two joints) are measured per frame; the rest keep their rest shape and are measured once here."""
        w = self.weights
        one_joint = (w > 0).sum(axis=1) == 1
        joint_of = np.where(one_joint, np.argmax(w, axis=1), -1)
        soft = ~one_joint | self.movable
        e0, e1 = self.edges[:, 0], self.edges[:, 1]
        act_e = soft[e0] | soft[e1] | (joint_of[e0] != joint_of[e1])
        f = self.faces
        area2 = np.linalg.norm(self.rest_normal, axis=1)
        act_f = (area2 > 1e-9 * max(float(area2.max(initial=0.0)), 1e-12)) & (
            soft[f].any(axis=1) | (joint_of[f[:, 0]] != joint_of[f[:, 1]]) | (joint_of[f[:, 0]] != joint_of[f[:, 2]])
        )  # degenerate rest triangles have no normal to flip: left out
        self._const_max = 1.0 if (~act_e).any() else 0.0
        self._const_min = 1.0 if (~act_e).any() else np.inf
        self._const_flips = 0
        verts = np.unique(np.concatenate([self.edges[act_e].ravel(), f[act_f].ravel()]))
        remap = np.full(len(self.rest), -1, dtype=np.int64)
        remap[verts] = np.arange(len(verts))
        self._v = verts
        self._act_e = act_e
        self._edges = remap[self.edges[act_e]]
        self._rest_len = self.rest_len[act_e]
        self._faces = remap[f[act_f]]
        self._rest_normal = self.rest_normal[act_f]
        self._rest_v = self.rest[verts]
        self._rest_vt = np.ascontiguousarray(self._rest_v.T)
        self._inv_rest_len2 = 1.0 / self.rest_len[act_e] ** 2
        self._w = self._w_used[verts]
        self._face_w = self._w_used[f[act_f]].mean(axis=1)
        self._w_t = np.ascontiguousarray(self._w.T)
        self._rest_normal32 = np.ascontiguousarray(self._rest_normal.T, dtype=np.float32)
        self._inv_rest_len2 = self._inv_rest_len2.astype(np.float32)
        self._face_w_t = np.ascontiguousarray(self._face_w.T)
        # single-frame fast path (`measure_one`): float32 tables, one index array per corner / edge end
        self._rest_vt32 = self._rest_vt.astype(np.float32)
        self._w_t32 = self._w_t.astype(np.float32)
        self._face_w_t32 = self._face_w_t.astype(np.float32)
        self.n_active_edges = int(act_e.sum())
        self.n_active_faces = int(act_f.sum())
        self._fast_subset(np.ones(len(self._edges), dtype=bool), np.ones(len(self._faces), dtype=bool))
        self._joints_used = [int(u) for u in self._used if u < self.weights.shape[1] - 1]  # the base slot left out
        # `measure_one_faces`' last keyed answer: (offsets key, static, subset, skinning joints' transforms, answer)
        self._last_one: tuple[bytes, tuple[float, float, int], int, FloatArray, _Measured] | None = None

    @property
    def joints_used(self) -> list[int]:
        """JointTree indices of the joints some skin vertex is weighted to (the head base left out)."""
        return list(self._joints_used)

    def _fast_subset(self, edges: NDArray[np.bool_], faces: NDArray[np.bool_]) -> None:
        """The active edges and faces `measure_one` measures (all of them, or the pull-driven ones), and
        the vertices they touch (`fast_vertices`). Each call is a new `subset` (a `FlipProbe` is of one)."""
        self.subset = getattr(self, "subset", 0) + 1
        sel = np.unique(np.concatenate([self._edges[edges].ravel(), self._faces[faces].ravel()]))
        remap = np.full(len(self._v), -1, dtype=np.int64)
        remap[sel] = np.arange(len(sel))
        self._fv = self._v[sel]
        self._frest_vt32 = np.ascontiguousarray(self._rest_vt32[:, sel])
        self._fw_t32 = np.ascontiguousarray(self._w_t32[:, sel])
        self._e0, self._e1 = (np.ascontiguousarray(remap[self._edges[edges, i]]) for i in range(2))
        self._f0, self._f1, self._f2 = (np.ascontiguousarray(remap[self._faces[faces, i]]) for i in range(3))
        self._fe_inv = np.ascontiguousarray(self._inv_rest_len2[edges])
        self._fn32 = np.ascontiguousarray(self._rest_normal32[:, faces])
        self._ffw_t32 = np.ascontiguousarray(self._face_w_t32[:, faces])

    def measure_only(self, edges: NDArray[np.bool_], faces: NDArray[np.bool_]) -> None:
        """Let `measure_one` measure only these of the active edges / faces (the rest proven within the
        limits in every pose: `skin_proof`)."""
        self._fast_subset(edges, faces)

    def split_static(self) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Leave out of `measure_one` the active edges and faces no anchor pull moves (their shape follows
        the joints alone, so the caller tabulates them: `measure_static`). Returns those (edge, face)
        masks over the active edges / faces."""
        mv = self.movable[self._v]
        static_e = ~mv[self._edges].any(axis=1)
        static_f = ~mv[self._faces].any(axis=1)
        self._fast_subset(~static_e, ~static_f)
        return static_e, static_f

    def measure_static(
        self, world: FloatArray, edges: NDArray[np.bool_], faces: NDArray[np.bool_]
    ) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """(max squared stretch, min squared stretch, flips) per (k, J, 4, 4) pose over some active edges
        and faces of the skin at rest offsets (float64; the tables behind `split_static`)."""
        mats = self._mats(world)  # (k, u, 12)
        m = np.swapaxes(mats, -1, -2) @ self._w_t  # (k, 12, nv)
        x, y, z = self._rest_vt
        p = [m[:, 4 * r] * x + m[:, 4 * r + 1] * y + m[:, 4 * r + 2] * z + m[:, 4 * r + 3] for r in range(3)]
        e = self._edges[edges]
        r2 = sum((c[:, e[:, 0]] - c[:, e[:, 1]]) ** 2 for c in p) * (1.0 / self.rest_len[self._act_e][edges] ** 2)
        f = self._faces[faces]
        u = np.stack([c[:, f[:, 1]] - c[:, f[:, 0]] for c in p], axis=-1)
        w = np.stack([c[:, f[:, 2]] - c[:, f[:, 0]] for c in p], axis=-1)
        rot = (np.swapaxes(mats, -1, -2) @ self._face_w_t[:, faces]).reshape(len(mats), 3, 4, -1)[:, :, :3]
        carried = np.einsum("kijf,fj->kfi", rot, self._rest_normal[faces])
        flips = (np.einsum("kfi,kfi->kf", np.cross(u, w), carried) <= 0.0).sum(axis=1)
        hi = r2.max(axis=1, initial=0.0) if r2.shape[1] else np.zeros(len(mats))
        lo = r2.min(axis=1, initial=np.inf) if r2.shape[1] else np.full(len(mats), np.inf)
        return (
            np.asarray(hi, dtype=np.float64),
            np.asarray(lo, dtype=np.float64),
            np.asarray(flips, dtype=np.int64),
        )

    @property
    def const_flips(self) -> int:
        """Flips `measure_one` adds to those it counts (the unmeasured skin's)."""
        return int(self._const_flips)

    @property
    def n_measured_faces(self) -> int:
        """Triangles `measure_one` measures (the indices a `FlipProbe` takes)."""
        return len(self._f0)

    @property
    def active_vertices(self) -> NDArray[np.int64]:
        """Indices of the vertices the strain check reads (sorted)."""
        return self._v

    @property
    def fast_vertices(self) -> NDArray[np.int64]:
        """Indices of the vertices `measure_one` reads (sorted; a subset of `active_vertices`)."""
        return np.asarray(self._fv, dtype=np.int64)

    def _normals(self, v: FloatArray) -> FloatArray:
        t = v[..., self.faces, :]
        return np.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :])

    def _mats(self, world: FloatArray) -> FloatArray:
        """(..., u, 12) the used joints' (3, 4) transforms, head base last."""
        if world.ndim == 3 and self._no_base:  # one pose skinned to joints only: gathered as they are
            return world[self._used, :3, :].reshape(len(self._used), 12)
        lead = world.shape[:-3]
        eye = np.broadcast_to(np.eye(4), (*lead, 1, 4, 4))
        mats = np.concatenate([world, eye], axis=-3)[..., self._used, :3, :]
        return mats.reshape(*lead, len(self._used), 12)

    def posed(self, world: FloatArray, offsets: FloatArray) -> FloatArray:
        """(..., n, 3) every posed skin vertex for (..., n, 3) offsets."""
        v = self.rest + offsets
        m = (self._w_used @ self._mats(world)).reshape(*v.shape[:-1], 3, 4)
        return np.asarray(np.einsum("...nij,...nj->...ni", m[..., :3], v) + m[..., 3], dtype=np.float64)

    def measure(self, world: FloatArray, offsets: FloatArray) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """(max stretch (...,), min compression (...,), flipped triangles (...,)) for (..., n, 3) offsets.

        Coordinates are kept as separate x, y, z arrays (vertices on the last axis): gathers and sums
        over 3-vectors are then plain element-wise work.
        """
        mats = self._mats(world)  # (..., u, 12)
        m = np.swapaxes(mats, -1, -2) @ self._w_t  # (..., 12, nv), rows contiguous
        m = np.moveaxis(m, -2, 0)
        # offsets of every vertex, or already of the active ones only (`active_vertices`)
        local = offsets if offsets.shape[-2] == len(self._v) else offsets[..., self._v, :]
        x = self._rest_vt[0] + local[..., 0]
        y = self._rest_vt[1] + local[..., 1]
        z = self._rest_vt[2] + local[..., 2]
        # float32 from here: ratios and signs need ~1e-6 relative precision, not 1e-15, at half the memory
        px = (m[0] * x + m[1] * y + m[2] * z + m[3]).astype(np.float32)
        py = (m[4] * x + m[5] * y + m[6] * z + m[7]).astype(np.float32)
        pz = (m[8] * x + m[9] * y + m[10] * z + m[11]).astype(np.float32)
        e0, e1 = self._edges[:, 0], self._edges[:, 1]
        dx, dy, dz = px[..., e0] - px[..., e1], py[..., e0] - py[..., e1], pz[..., e0] - pz[..., e1]
        r2 = (dx * dx + dy * dy + dz * dz) * self._inv_rest_len2
        r = np.moveaxis(np.swapaxes(mats, -1, -2) @ self._face_w_t, -2, 0).astype(np.float32)
        n0, n1, n2 = self._rest_normal32
        ex, ey, ez = (
            r[0] * n0 + r[1] * n1 + r[2] * n2,
            r[4] * n0 + r[5] * n1 + r[6] * n2,
            r[8] * n0 + r[9] * n1 + r[10] * n2,
        )
        f0, f1, f2 = self._faces[:, 0], self._faces[:, 1], self._faces[:, 2]
        ux, uy, uz = px[..., f1] - px[..., f0], py[..., f1] - py[..., f0], pz[..., f1] - pz[..., f0]
        wx, wy, wz = px[..., f2] - px[..., f0], py[..., f2] - py[..., f0], pz[..., f2] - pz[..., f0]
        dot = (uy * wz - uz * wy) * ex + (uz * wx - ux * wz) * ey + (ux * wy - uy * wx) * ez
        flipped = dot <= 0.0
        stretch = np.maximum(np.sqrt(r2.max(axis=-1, initial=0.0).astype(np.float64)), self._const_max)
        comp = np.minimum(np.sqrt(r2.min(axis=-1, initial=np.inf).astype(np.float64)), self._const_min)
        return stretch, comp, flipped.sum(axis=-1) + self._const_flips

    def measure_one(
        self,
        world: FloatArray,
        offsets: FloatArray,
        static: tuple[float, float, int] = (0.0, np.inf, 0),
        offsets_key: bytes | None = None,
    ) -> tuple[float, float, int]:
        """`measure_one_faces` without the flipped triangles."""
        stretch, comp, flips, _ = self._measured(world, offsets, static, offsets_key)
        return stretch, comp, flips

    def measure_one_faces(
        self,
        world: FloatArray,
        offsets: FloatArray,
        static: tuple[float, float, int] = (0.0, np.inf, 0),
        offsets_key: bytes | None = None,
    ) -> tuple[float, float, int, NDArray[np.bool_]]:
        """`measure` for one frame: (J, 4, 4) transforms and the offsets of the active vertices only
        (`fast_vertices`, (nv, 3)). Same quantities as `measure` (float32 from the transforms on, in
        place, each corner gathered once): about half its cost per frame. Also which measured triangles
        flipped ((nf,) mask, in the order `FlipProbe` indexes them).

        ``offsets_key``: the caller's name for these offsets (equal keys for equal offsets, e.g.
        `SkinSource.rows_key`): with it, the last answer is returned again for the same key, the same
        transforms of the skinning joints and the same ``static`` (the numbers depend on nothing else)."""
        stretch, comp, flips, flipped = self._measured(world, offsets, static, offsets_key)
        # with a key the mask is also the one kept: the caller gets a copy, so it cannot change a later answer
        return stretch, comp, flips, (flipped if offsets_key is None else flipped.copy())

    def _measured(
        self, world: FloatArray, offsets: FloatArray, static: tuple[float, float, int], offsets_key: bytes | None
    ) -> _Measured:
        """`_measure_one_faces`, or its last keyed answer again (see `measure_one_faces`): the cheap parts of
        the key are compared first, the skinning joints' transforms (dtype, shape, bytes) only when they agree."""
        if offsets_key is None:
            return self._measure_one_faces(world, offsets, static)
        used = world[self._joints_used]  # a copy (integer index): the caller's later changes do not reach it
        last = self._last_one
        if last is not None and last[0] == offsets_key and last[1] == static and last[2] == self.subset:
            kept = last[3]
            if kept.dtype == used.dtype and kept.shape == used.shape and kept.tobytes() == used.tobytes():
                return last[4]
        out = self._measure_one_faces(world, offsets, static)
        self._last_one = (offsets_key, static, self.subset, used, out)
        return out

    def _measure_one_faces(
        self, world: FloatArray, offsets: FloatArray, static: tuple[float, float, int]
    ) -> tuple[float, float, int, NDArray[np.bool_]]:
        """The measure itself. The posed vertices are kept as 16-byte records (x, y, z, 0 in float32) so
        that each gather (an edge end, a triangle corner) moves a whole vertex in one ``take`` (one index
        check per vertex instead of one per coordinate); the arithmetic is the same float32 products in the
        same order (on x, y, z rows copied out of the gathered records), so the numbers are those of one
        gather per coordinate."""
        mats = self._mats(world).astype(np.float32)  # (u, 12)
        m = mats.T @ self._fw_t32  # (12, nv)
        o = offsets.T.astype(np.float32)
        recs = _pose_records(m, self._frest_vt32, o)  # (nv,) 16-byte records
        d = _gathered(recs, self._e0)
        d -= _gathered(recs, self._e1)  # edge vectors (x, y, z, 0)
        d *= d
        dt = d.T[:3].copy()  # x, y, z rows (contiguous: the sums below run on whole rows)
        dx = dt[0] + dt[1]
        dx += dt[2]
        dx *= self._fe_inv  # squared stretch ratio per measured edge
        r = mats.T @ self._ffw_t32  # (12, nf) blended transform per face
        n0, n1, n2 = self._fn32
        ex = r[0] * n0
        ex += r[1] * n1
        ex += r[2] * n2
        ey = r[4] * n0
        ey += r[5] * n1
        ey += r[6] * n2
        ez = r[8] * n0
        ez += r[9] * n1
        ez += r[10] * n2
        a = _gathered(recs, self._f0)
        u = _gathered(recs, self._f1)
        u -= a
        w = _gathered(recs, self._f2)
        w -= a
        ux, uy, uz = u.T[:3].copy()
        wx, wy, wz = w.T[:3].copy()
        cx = uy * wz
        cx -= uz * wy
        cx *= ex
        cy = uz * wx
        cy -= ux * wz
        cy *= ey
        cz = ux * wy
        cz -= uy * wx
        cz *= ez
        cx += cy
        cx += cz  # posed normal . carried rest normal
        hi2 = max(float(dx.max()), static[0]) if dx.size else static[0]
        lo2 = min(float(dx.min()), static[1]) if dx.size else static[1]
        stretch = max(float(np.sqrt(hi2)), self._const_max)
        comp = min(float(np.sqrt(lo2)), self._const_min)
        flipped = cx <= 0.0
        return stretch, comp, int(np.count_nonzero(flipped)) + self._const_flips + static[2], flipped


@dataclass(frozen=True)
class FlipProbe:
    """Some of the triangles `SkinTwin.measure_one` measures (``faces``: indices into them), with the
    vertices they need (``verts``: indices into `fast_vertices`) and each corner's place among those."""

    subset: int  # `SkinTwin.subset` it was made for
    faces: NDArray[np.int64]
    verts: NDArray[np.int64]
    corners: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]
    normals: NDArray[np.float32]  # (3, p) rest normals of the triangles
    rest32: NDArray[np.float32]  # (3, q) rest x, y, z of the vertices


def flip_probe(skin: SkinTwin, faces: NDArray[np.int64]) -> FlipProbe:
    """The probe of these measured triangles (indices into the faces `measure_one` measures)."""
    f = np.asarray(faces, dtype=np.int64)
    corners = np.stack([skin._f0[f], skin._f1[f], skin._f2[f]])
    verts, inv = np.unique(corners, return_inverse=True)
    inv = inv.reshape(corners.shape)
    normals = np.ascontiguousarray(skin._fn32[:, f])
    rest = np.ascontiguousarray(skin._frest_vt32[:, verts])
    return FlipProbe(skin.subset, f, verts, (inv[0], inv[1], inv[2]), normals, rest)


def probe_dots(skin: SkinTwin, world: FloatArray, offsets: FloatArray, probe: FlipProbe) -> NDArray[np.float32]:
    """Posed normal . carried rest normal of the probe's triangles, the same numbers `measure_one` computes
    for them (the same float32 products in the same order, elementwise on the probe's vertices and
    triangles, x / y / z stacked as rows; the two blend products are the whole ones, gathered), so a
    triangle flips here exactly when it flips there."""
    return probe_dots_at(skin, world, offsets.take(probe.verts, axis=0), probe)


def probe_dots_at(
    skin: SkinTwin, world: FloatArray, probe_offsets: FloatArray, probe: FlipProbe
) -> NDArray[np.float32]:
    """`probe_dots` from the offsets of the probe's vertices only ((len(probe.verts), 3), in its order)."""
    if probe.subset != skin.subset:
        raise GateConfigError("flip probe made for another measured subset of the skin")
    mats = skin._mats(world).astype(np.float32)
    m = (mats.T @ skin._fw_t32).take(probe.verts, axis=1).reshape(3, 4, -1)  # [coordinate, column, vertex]
    v = probe.rest32 + probe_offsets.T.astype(np.float32)
    p = m[:, 0] * v[0]
    p += m[:, 1] * v[1]
    p += m[:, 2] * v[2]
    p += m[:, 3]  # posed x, y, z rows
    r = (mats.T @ skin._ffw_t32).take(probe.faces, axis=1).reshape(3, 4, -1)
    n = probe.normals
    e = r[:, 0] * n[0]
    e += r[:, 1] * n[1]
    e += r[:, 2] * n[2]  # carried rest normal rows
    f0, f1, f2 = probe.corners
    a = p.take(f0, axis=1)
    u = p.take(f1, axis=1)
    u -= a
    w = p.take(f2, axis=1)
    w -= a
    c = u[_NEXT] * w[_AFTER]
    c -= u[_AFTER] * w[_NEXT]  # posed normal (u x w) rows
    c *= e
    out = c[0] + c[1]
    out += c[2]
    return np.asarray(out, dtype=np.float32)


_NEXT = np.array([1, 2, 0])
_AFTER = np.array([2, 0, 1])


_RECORD = np.dtype((np.void, 16))  # one posed vertex: x, y, z, 0 as float32


def _pose_records(m: NDArray[np.float32], rv: NDArray[np.float32], o: NDArray[np.float32]) -> NDArray[np.void]:
    """(nv,) 16-byte records (x, y, z, 0 in float32) of the posed vertices from their (12, nv) blended
    transforms, rest (3, nv) and offsets: per coordinate m0 x + m1 y + m2 z + m3, accumulated in that order."""
    x, y, z = rv[0] + o[0], rv[1] + o[1], rv[2] + o[2]
    out = np.zeros((rv.shape[1], 4), dtype=np.float32)
    for row in range(3):
        col = out[:, row]
        np.multiply(m[4 * row], x, out=col)
        col += m[4 * row + 1] * y
        col += m[4 * row + 2] * z
        col += m[4 * row + 3]
    return out.view(_RECORD).reshape(-1)


def _gathered(records: NDArray[np.void], index: NDArray[np.int64]) -> NDArray[np.float32]:
    """(len(index), 4) float32: the records at ``index`` (one ``take``), as x, y, z, 0 columns."""
    return records.take(index).view(np.float32).reshape(-1, 4)


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
