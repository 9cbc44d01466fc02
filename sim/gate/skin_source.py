"""Where the twin's skin offsets come from, cheaply per frame.

With the face model (MUSCLES' twin, `FaceModel.pose_from_targets`): the muscle contractions are its
bounded least-squares fit to the anchor pulls (solved here by the warm-started `box_lsq.BoxLsq`: the
same unique minimiser as ``fm.fit.contractions``), the skin is its muscle field for those contractions
(``fm.field.offsets``) plus its smooth anchor bumps for what the muscles leave unexplained
(``fm.fit.bumps``, linear in the residual, so precomputed as a matrix). That is the face model's own skin
(tested against ``pose_from_targets``) without its per-call cost.
Without a face model: a raised-cosine falloff per anchor (linear in the pulls).
``movable`` marks the vertices any pull can move; the strain check only re-measures around them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from servoface.sim.gate.box_lsq import BoxLsq
from servoface.sim.gate.errors import GateConfigError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class SkinSource:
    """offsets(p) = base + field(c(p)) + Bm @ (p - L @ c(p)) for absolute anchor pulls p (A,) in mm."""

    base: FloatArray  # (n, 3)
    bumps: FloatArray  # (3n, A)
    unit_pull: FloatArray  # (A, M)
    contract: Callable[[FloatArray], FloatArray] | None  # p -> c (M,), None = no muscles
    field: Callable[[FloatArray], FloatArray] | None  # c -> (n, 3)
    lower_mm: FloatArray
    upper_mm: FloatArray
    movable: BoolArray  # (n,)
    field_rows: Callable[[FloatArray, NDArray[np.int64]], FloatArray] | None = None  # field(c)[rows], cheaper
    # rows -> (c -> field(c)[rows]): the same numbers as ``field_rows``, prepared once for a caller that keeps it
    field_part: Callable[[NDArray[np.int64]], Callable[[FloatArray], FloatArray]] | None = None
    _rows: dict[int, tuple[NDArray[np.int64], Any, FloatArray]] = dc_field(default_factory=dict)
    # `offsets_rows`' last answer per row set: (rows, clipped pulls, contractions, offsets); not copied by
    # dataclasses.replace (init=False), so a replaced source starts without it
    _last: dict[int, tuple[NDArray[np.int64], bytes, bytes, FloatArray]] = dc_field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def offsets(self, pulls_mm: FloatArray) -> FloatArray:
        """(n, 3) skin offsets for one pull vector (A,), clamped to the actuator ranges first."""
        p = np.clip(pulls_mm, self.lower_mm, self.upper_mm)
        if self.contract is None or self.field is None:
            return self.base + (self.bumps @ p).reshape(-1, 3)
        c = self.contract(p)
        return self.base + self.field(c) + (self.bumps @ (p - self.unit_pull @ c)).reshape(-1, 3)

    def offsets_rows(self, pulls_mm: FloatArray, rows: NDArray[np.int64]) -> FloatArray:
        """(len(rows), 3) offsets of some vertices only (the strain check's active set).

        They are a function of the clipped pulls and the contractions fitted to them: when both are the
        last call's for these rows (a frame whose pulls did not move), that call's offsets are returned
        again (a copy) instead of recomputed."""
        key = id(rows)
        cached = self._rows.get(key)
        if cached is None or cached[0] is not rows:
            cached = (rows, self._bump_rows(rows), self.base[rows])
            self._rows[key] = cached
        _, bumps, base = cached
        p = np.clip(pulls_mm, self.lower_mm, self.upper_mm)
        c = None if self.contract is None or self.field is None else self.contract(p)
        p_key, c_key = p.tobytes(), b"" if c is None else c.tobytes()
        last = self._last.get(key)
        if last is not None and last[0] is rows and last[1] == p_key and last[2] == c_key:
            return last[3].copy()
        out = self._offsets_rows(p, c, rows, bumps, base)
        self._last[key] = (rows, p_key, c_key, out.copy())
        return out

    def rows_part(self, rows: NDArray[np.int64]) -> RowsPart:
        """What `offsets_part` needs for these rows, prepared once (the caller keeps it; nothing is cached
        here, so a short-lived row set costs no memory after its holder drops it)."""
        rows = np.asarray(rows, dtype=np.int64)
        field = None if self.field_part is None else self.field_part(rows)
        return RowsPart(rows, self._bump_rows(rows), self.base[rows], field)

    def _bump_rows(self, rows: NDArray[np.int64]) -> Any:
        """The anchor bumps' rows of these vertices, sparse (bumps are local, a few % non-zero: the product
        is ~10x cheaper); explicit shapes: a head may have no skin or no anchors (size 0)."""
        n_anchor = self.bumps.shape[1]
        return sp.csr_matrix(self.bumps.reshape(len(self.base), 3, n_anchor)[rows].reshape(3 * len(rows), n_anchor))

    def offsets_part(self, pulls_mm: FloatArray, part: RowsPart) -> FloatArray:
        """(len(part.rows), 3): `offsets_rows` of the part's rows, bit for bit — each offset is a function of
        its own row only (sparse row sums in the same order, the sphincters' displacements gathered, the
        same contractions: `BoxLsq` answers a repeated fit from its memory), computed on those rows alone."""
        p = np.clip(pulls_mm, self.lower_mm, self.upper_mm)
        c = None if self.contract is None or self.field is None else self.contract(p)
        return self._offsets_rows(p, c, part.rows, part.bumps, part.base, part.field)

    def rows_key(self, rows: NDArray[np.int64]) -> bytes | None:
        """What the last `offsets_rows` answer for ``rows`` was computed from (clipped pulls and fitted
        contractions): equal keys mean equal offsets. None before any."""
        last = self._last.get(id(rows))
        return None if last is None or last[0] is not rows else last[1] + b"|" + last[2]

    def _offsets_rows(
        self,
        p: FloatArray,
        c: FloatArray | None,
        rows: NDArray[np.int64],
        bumps: Any,
        base: FloatArray,
        field_of: Callable[[FloatArray], FloatArray] | None = None,
    ) -> FloatArray:
        """base + field(c)[rows] + bumps' rows @ (p - L c); ``field_of``: c -> field(c)[rows] prepared."""
        if c is None or self.field is None:
            return np.asarray(base + (bumps @ p).reshape(-1, 3), dtype=np.float64)
        fit = np.asarray(bumps @ (p - self.unit_pull @ c), dtype=np.float64).reshape(-1, 3)
        if field_of is not None:
            return base + field_of(c) + fit
        if self.field_rows is not None:
            return base + self.field_rows(c, rows) + fit
        return base + np.take(self.field(c), rows, axis=0) + fit  # take: a row gather ~5x faster

    def offsets_batch(self, pulls_mm: FloatArray) -> FloatArray:
        """(k, n, 3) for (k, A) pulls."""
        p = np.clip(pulls_mm, self.lower_mm, self.upper_mm)
        if self.contract is None:
            return self.base + (p @ self.bumps.T).reshape(p.shape[0], len(self.base), 3)
        return np.stack([self.offsets(row) for row in p])


@dataclass(frozen=True)
class RowsPart:
    """Some skin rows prepared for `SkinSource.offsets_part` (`SkinSource.rows_part`)."""

    rows: NDArray[np.int64]
    bumps: Any  # (3 len(rows), A) sparse rows of the anchor bumps
    base: FloatArray  # (len(rows), 3)
    field: Callable[[FloatArray], FloatArray] | None  # c -> field(c)[rows]


def _support(flat_cols: FloatArray) -> BoolArray:
    return np.asarray(np.abs(flat_cols).reshape(-1, 3, flat_cols.shape[-1]).sum(axis=(1, 2)) > 0)


def falloff_source(skin: Any, anchors: Sequence[Any]) -> SkinSource:
    """Each anchor drags the skin within ``radius_mm`` of its vertex along its line (raised cosine)."""
    v = np.asarray(skin.vertices_mm, dtype=np.float64)
    cols = []
    for a in anchors:
        d = np.linalg.norm(v - v[a.vertex], axis=1) / max(float(a.radius_mm), 1e-9)
        w = np.where(d < 1.0, 0.5 * (1.0 + np.cos(np.pi * np.minimum(d, 1.0))), 0.0)
        line = np.asarray(a.line, dtype=np.float64)
        cols.append((w[:, None] * (line / np.linalg.norm(line))[None, :]).reshape(-1))
    bumps = np.stack(cols, axis=1) if cols else np.zeros((v.size, 0))
    neutral = np.array([a.neutral_mm for a in anchors], dtype=np.float64)
    return SkinSource(
        base=-(bumps @ neutral).reshape(-1, 3),
        bumps=bumps,
        unit_pull=np.zeros((len(anchors), 0)),
        contract=None,
        field=None,
        lower_mm=np.array([a.lower_mm for a in anchors], dtype=np.float64),
        upper_mm=np.array([a.upper_mm for a in anchors], dtype=np.float64),
        movable=_support(bumps) if cols else np.zeros(len(v), dtype=bool),
    )


def face_model_source(face_model: Any, anchors: Sequence[Any]) -> SkinSource:
    """The face model's twin skin (see module docstring)."""
    fm = face_model
    if getattr(fm.field, "eyelids", None):
        raise GateConfigError(
            "the face model moves skin with joint angles (eyelid muscles); the gate's skin needs offsets "
            "that depend on the anchor pulls only"
        )
    model_roles = [a.role for a in fm.anchor_actuators]
    if model_roles != [a.role for a in anchors]:
        raise GateConfigError(f"face model anchors {model_roles} differ from the gate's {[a.role for a in anchors]}")
    n = int(fm.n_vertices)
    n_muscles = len(fm.field.names)
    n_anchors = len(anchors)
    bumps = (
        np.stack([np.asarray(fm.fit.bumps(np.eye(n_anchors)[a])).reshape(-1) for a in range(n_anchors)], axis=1)
        if n_anchors
        else np.zeros((3 * n, 0))
    )
    movable = _support(bumps) if n_anchors else np.zeros(n, dtype=bool)
    low, high = float(fm.fit.low), float(fm.fit.high)
    for m in range(n_muscles):
        for value in (low, high, 0.5 * (low + high)):
            c = np.zeros(n_muscles)
            c[m] = value
            movable |= np.abs(np.asarray(fm.field.offsets(c))).sum(axis=1) > 0
    unit_pull = np.asarray(fm.fit.unit_pull, dtype=np.float64)
    if n_muscles == 0:  # anchors only (or nothing at all): the face model's skin is its anchor bumps
        return SkinSource(
            base=np.zeros((n, 3)),
            bumps=bumps,
            unit_pull=unit_pull.reshape(n_anchors, 0),
            contract=None,
            field=None,
            lower_mm=np.array([a.lower_mm for a in anchors], dtype=np.float64),
            upper_mm=np.array([a.upper_mm for a in anchors], dtype=np.float64),
            movable=movable,
        )
    solver = BoxLsq(np.vstack([unit_pull, float(fm.fit.mu) * np.eye(n_muscles)]), low, high)
    zeros = np.zeros(n_muscles)

    def contract(p: FloatArray) -> FloatArray:
        c = solver.solve(np.concatenate([p, zeros]))
        return np.asarray(fm.fit.contractions(p), dtype=np.float64) if c is None else c

    return SkinSource(
        base=np.zeros((n, 3)),
        bumps=bumps,
        unit_pull=unit_pull,
        contract=contract,
        field=lambda c: np.asarray(fm.field.offsets(c), dtype=np.float64),
        lower_mm=np.array([a.lower_mm for a in anchors], dtype=np.float64),
        upper_mm=np.array([a.upper_mm for a in anchors], dtype=np.float64),
        movable=movable,
        field_rows=_field_rows(fm.field),
        field_part=_field_part(fm.field),
    )


def _field_rows(field: Any) -> Callable[[FloatArray, NDArray[np.int64]], FloatArray]:
    """``field.offsets(c)[rows]`` computed on those rows only: the linear part's rows of the sparse matrix
    (each row's sum is the same products in the same order) plus the sphincters' displacements at the rows
    they reach, added in the same order — the same numbers as the whole field, gathered. Prepared once per
    row set (by identity)."""
    cache: dict[int, tuple[NDArray[np.int64], Callable[[FloatArray], FloatArray]]] = {}
    part = _field_part(field)

    def rows_of(c: FloatArray, rows: NDArray[np.int64]) -> FloatArray:
        got = cache.get(id(rows))
        if got is None or got[0] is not rows:
            got = (rows, part(rows))
            cache[id(rows)] = got
        return got[1](c)

    return rows_of


def _field_part(field: Any) -> Callable[[NDArray[np.int64]], Callable[[FloatArray], FloatArray]]:
    """rows -> (c -> ``field.offsets(c)[rows]``): see `_field_rows`."""

    def prepare(rows: NDArray[np.int64]) -> Callable[[FloatArray], FloatArray]:
        flat = (3 * rows[:, None] + np.arange(3)[None, :]).ravel()
        matrix = field.linear_matrix[flat]
        where = np.full(field.n_vertices, -1, dtype=np.int64)
        where[rows] = np.arange(len(rows))
        caps: list[tuple[int, Any, NDArray[np.int64] | None, NDArray[np.int64]]] = []
        for col, sph in field.sphincters:
            pos = where[sph.index]
            inside = np.flatnonzero(pos >= 0)
            # flat (x, y, z) indices: a sphincter's rows are added with one take and one put on the flat
            # arrays (the same sums as `out[pos] += disp[inside]`, ~3x cheaper); all of it inside: no gather
            whole = len(inside) == len(pos)
            caps.append((int(col), sph, None if whole else _xyz(inside), _xyz(pos[inside])))
        n = len(rows)

        def of(c: FloatArray) -> FloatArray:
            out = np.asarray(matrix @ c, dtype=np.float64)  # (3n,): x, y, z per row
            for col, sph, inside3, pos3 in caps:
                if c[col] != 0.0:
                    disp = np.asarray(sph.displacement(float(c[col]))).reshape(-1)
                    out.put(pos3, out.take(pos3) + (disp if inside3 is None else disp.take(inside3)))
            return out.reshape(n, 3)

        return of

    return prepare


def _xyz(rows: NDArray[np.int64]) -> NDArray[np.int64]:
    """Flat indices of the x, y, z entries of these rows of an (n, 3) array."""
    return np.asarray((3 * rows[:, None] + np.arange(3)[None, :]).ravel(), dtype=np.int64)
