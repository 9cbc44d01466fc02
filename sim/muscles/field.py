"""All muscles of a skin, precomputed once on the rest mesh (muscle-models.md §1.5).

Linear and sheet muscles are linear in their contraction, so each becomes a fixed sparse vector field
W_m and a frame is ``x_rest + Σ_m c_m W_m``: one sparse matrix-vector product, independent of muscle
order. Sphincters add a per-vertex cap (never past the centre) and eyelids turn their few vertices by the
lid joint angle; both are evaluated per frame on their small vertex sets only.

Given the skin's ``faces``, a linear or sheet field that reaches a slit (the lips) is gated by
``servoface.sim.muscles.slit`` from the skin vertex nearest its insertion (a sheet: the middle of its
insertion edge): it moves the far side of the slit only as far as it reaches it round the slit's ends, so
a lip muscle moves its own lip and the lips can part (AU10, AU16), while a muscle inserting at a mouth
corner (AU12, AU14, AU15, AU20) moves both lips as before.

The build looks up the vertices near a linear muscle's attachment (within rf) and the vertex nearest an
insertion in a k-d tree (``servoface.sim.muscles.near``) instead of measuring every vertex per muscle; the
fields are the same arrays (`tests/sim/test_muscle_build_equivalence.py`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from servoface.sim.muscles.eyelid import EyelidField, EyelidMuscle
from servoface.sim.muscles.linear import LinearMuscle
from servoface.sim.muscles.near import NearVertices
from servoface.sim.muscles.sheet import SheetMuscle
from servoface.sim.muscles.slit import SlitGate, slit_gate
from servoface.sim.muscles.sphincter import SphincterField, SphincterMuscle

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
VectorMuscle = LinearMuscle | SheetMuscle | SphincterMuscle


class MuscleField:
    """The displacement model of one skin: contractions (M,) -> skin offsets (n, 3) mm, from rest.

    ``names`` fixes the order of the contraction vector: the vector muscles (linear, sheet, sphincter)
    in the given order. Eyelid muscles are kept apart (``eyelids``): they are driven by joint angles.
    """

    def __init__(
        self,
        muscles: Sequence[VectorMuscle | EyelidMuscle],
        rest_mm: FloatArray,
        faces: NDArray[np.integer] | None = None,
    ) -> None:
        rest = np.asarray(rest_mm, dtype=np.float64)
        self.slit: SlitGate | None = slit_gate(rest, faces) if faces is not None else None
        self.n_vertices = int(rest.shape[0])
        gated = self.slit is not None and self.slit.has_slit
        self.near: NearVertices = self.slit.near if self.slit is not None and gated else NearVertices(rest)
        vector = [m for m in muscles if not isinstance(m, EyelidMuscle)]
        self.names: tuple[str, ...] = tuple(m.name for m in vector)
        self.index: dict[str, int] = {name: i for i, name in enumerate(self.names)}
        rows: list[IntArray] = []
        cols: list[IntArray] = []
        vals: list[FloatArray] = []
        self.sphincters: list[tuple[int, SphincterField]] = []
        for col, muscle in enumerate(vector):
            if isinstance(muscle, SphincterMuscle):
                self.sphincters.append((col, muscle.field(rest)))
                continue
            idx, disp = self._unit_field(muscle, rest)
            if self.slit is not None and self.slit.has_slit and idx.size and self.slit.on_slit[idx].any():
                source = self.near.nearest(_insertion_mm(muscle))
                disp = disp * self.slit.gate(source, idx)[:, None]
            rows.append((3 * idx[:, None] + np.arange(3)[None, :]).ravel())
            cols.append(np.full(3 * idx.size, col, dtype=np.int64))
            vals.append(disp.ravel())
        n_rows, n_cols = 3 * self.n_vertices, len(vector)
        if rows:
            w = sp.csr_matrix(
                (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_rows, n_cols)
            )
        else:
            w = sp.csr_matrix((n_rows, n_cols))
        w.eliminate_zeros()
        self.linear_matrix: sp.csr_matrix = w
        self._subsets: dict[bytes, Any] = {}  # `offsets_at`: row subsets per vertex list
        self.eyelids: list[tuple[EyelidMuscle, EyelidField]] = [
            (m, m.field(rest)) for m in muscles if isinstance(m, EyelidMuscle)
        ]

    def _unit_field(self, muscle: LinearMuscle | SheetMuscle, rest: FloatArray) -> tuple[IntArray, FloatArray]:
        """``muscle.unit_field(rest)``; a linear muscle's from the vertices within its rf of its attachment
        only (it moves no other vertex, and its arithmetic is per vertex)."""
        if not isinstance(muscle, LinearMuscle):
            return muscle.unit_field(rest)
        cand = self.near.within(np.asarray(muscle.attachment_mm, dtype=np.float64), muscle.rf_mm)
        idx, disp = muscle.unit_field(rest[cand])
        return cand[idx], disp

    def offsets(self, contractions: FloatArray, joint_deg: Mapping[str, float] | None = None) -> FloatArray:
        """Skin offsets (n, 3) mm for contractions (M,) (already clamped by the caller) and lid angles."""
        c = np.asarray(contractions, dtype=np.float64)
        out = (self.linear_matrix @ c).reshape(self.n_vertices, 3)
        for col, field in self.sphincters:
            if c[col] != 0.0:
                out[field.index] += field.displacement(float(c[col]))
        if joint_deg:
            for muscle, lid in self.eyelids:
                angle = float(joint_deg.get(muscle.joint, 0.0))
                if angle != 0.0:
                    out[lid.index] += lid.displacement(angle)
        return np.asarray(out, dtype=np.float64)

    def offsets_at(
        self, contractions: FloatArray, vertices: IntArray, joint_deg: Mapping[str, float] | None = None
    ) -> FloatArray:
        """``offsets(contractions, joint_deg)[vertices]`` (len(vertices), 3) mm, computed on those vertices
        only (e.g. the actuator anchors, for targets without the skin). The same arithmetic row by row: a
        CSR row's products summed in the same order, then each sphincter's and lid's term added, in the same
        order. The row subset is built once per vertex list."""
        c = np.asarray(contractions, dtype=np.float64)
        if len(vertices) == 0:
            return np.zeros((0, 3))
        plan = self._subset(np.asarray(vertices, dtype=np.int64))
        w, n_unique, inverse, sphincters, lids = plan
        out = (w @ c).reshape(n_unique, 3)
        for col, field, at, take in sphincters:
            if c[col] != 0.0:
                out[at] += field.displacement(float(c[col]))[take]
        if joint_deg:
            for muscle, lid, at, take in lids:
                angle = float(joint_deg.get(muscle.joint, 0.0))
                if angle != 0.0:
                    out[at] += lid.displacement(angle)[take]
        return np.asarray(out[inverse], dtype=np.float64)

    def _subset(self, vertices: IntArray) -> tuple[sp.csr_matrix, int, IntArray, list[Any], list[Any]]:
        key = vertices.tobytes()
        plans = self._subsets
        plan = plans.get(key)
        if plan is None:
            unique, inverse = np.unique(vertices, return_inverse=True)
            rows = (3 * unique[:, None] + np.arange(3)[None, :]).ravel()
            w = self.linear_matrix[rows]
            where = {int(v): i for i, v in enumerate(unique)}

            def hits(index: IntArray) -> tuple[IntArray, IntArray]:
                pairs = [(where[int(v)], k) for k, v in enumerate(index) if int(v) in where]
                at = np.array([a for a, _ in pairs], dtype=np.int64)
                return at, np.array([k for _, k in pairs], dtype=np.int64)

            sphincters = [(col, f, *hits(f.index)) for col, f in self.sphincters]
            lids = [(m, lid, *hits(lid.index)) for m, lid in self.eyelids]
            plan = plans[key] = (w, int(unique.size), inverse.astype(np.int64), sphincters, lids)
        return plan

    def unit_displacements(self, vertices: Sequence[int] | IntArray) -> FloatArray:
        """(len(vertices), 3, M) displacement per unit contraction at the given vertices (caps ignored)."""
        verts = np.asarray(vertices, dtype=np.int64)
        rows = (3 * verts[:, None] + np.arange(3)[None, :]).ravel()
        dense = self.linear_matrix[rows].toarray().reshape(verts.size, 3, len(self.names))
        for col, field in self.sphincters:
            lookup = {int(v): k for k, v in enumerate(field.index)}
            for i, v in enumerate(verts):
                k = lookup.get(int(v))
                if k is not None:
                    dense[i, :, col] += field.gain_mm[k] * field.direction[k]
        return np.asarray(dense, dtype=np.float64)


def _insertion_mm(muscle: LinearMuscle | SheetMuscle) -> FloatArray:
    """Where a vector muscle grips the skin: its insertion (a sheet: the middle of its insertion edge)."""
    if isinstance(muscle, SheetMuscle):
        mid = (np.asarray(muscle.insertion_mm) + np.asarray(muscle.insertion_end_mm)) / 2.0
        return np.asarray(mid, dtype=np.float64)
    return np.asarray(muscle.insertion_mm, dtype=np.float64)
