"""All of a head's servo curves evaluated at once on (k, S) arrays: the fast path for the twin gate.

Forward (target -> tick): every curve is turned into padded polynomial pieces (see ``Curve.pieces``), so
one gather and one Horner evaluation serve all servos and all rows together, exactly.

Inverse (tick -> target): goals are integers, so each servo's inverse is tabulated at every integer tick
of its limits (computed once with the curve's exact inverse); a goal is a table lookup, a fractional tick
is interpolated between its two neighbours.

Range checks are vectorised too and raise the same typed errors as :class:`ServoCalibration`, naming
the first offending servo.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from servoface.calibration.errors import TargetOutOfRangeError, TickOutOfRangeError
from servoface.calibration.servo import ServoCalibration, round_ticks

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class CurveBank:
    """The curves of ``servos`` (column order) as one vectorised evaluator."""

    def __init__(self, servos: Sequence[ServoCalibration]) -> None:
        self.servos = tuple(servos)
        n = len(self.servos)
        parts = [s.curve.pieces() for s in self.servos]
        width = max(len(k) for k, _, _ in parts)
        self._knots = np.full((n, width), np.inf)
        self._base = np.zeros((n, width + 1))
        self._coef = np.zeros((n, width + 1, 4))
        for j, (knots, base, coef) in enumerate(parts):
            self._knots[j, : len(knots)] = knots
            self._base[j, : len(base)] = base
            self._coef[j, : len(coef)] = coef
        self._cols = np.arange(n)
        # `forward_row`'s flat tables: piece k of column j at j * (width + 1) + k, one array per coefficient
        self._row_piece = self._cols * (width + 1)
        self._flat_base = self._base.ravel()
        self._flat_coef = tuple(np.ascontiguousarray(self._coef[:, :, d]).ravel() for d in range(4))
        self.min_target = np.array([s.min_target for s in self.servos])
        self.max_target = np.array([s.max_target for s in self.servos])
        self._accept_lo = np.array([s.accept_min_target for s in self.servos])
        self._accept_hi = np.array([s.accept_max_target for s in self.servos])
        self.min_tick = np.array([s.min_tick for s in self.servos], dtype=np.int64)
        self.max_tick = np.array([s.max_tick for s in self.servos], dtype=np.int64)
        # inverse tables: targets at every integer tick min_tick..max_tick, padded with the last value
        length = int(np.max(self.max_tick - self.min_tick)) + 2
        self._table = np.empty((n, length))
        for j, s in enumerate(self.servos):
            values = s.curve.inverse(np.arange(s.min_tick, s.max_tick + 1, dtype=np.float64))
            self._table[j, : len(values)] = values
            self._table[j, len(values) :] = values[-1]
        self._flat_table = self._table.ravel()
        self._row_start = np.arange(n) * length

    def forward(self, targets: ArrayLike) -> FloatArray:
        """(k, S) targets -> (k, S) float ticks (no range check, straight continuation outside)."""
        t = np.asarray(targets, dtype=np.float64)
        idx = (t[..., None] >= self._knots).sum(axis=-1)
        cols = np.broadcast_to(self._cols, t.shape)
        c = self._coef[cols, idx]
        dx = t - self._base[cols, idx]
        return np.asarray(c[..., 0] + dx * (c[..., 1] + dx * (c[..., 2] + dx * c[..., 3])), dtype=np.float64)

    def check_targets(self, targets: ArrayLike) -> FloatArray:
        """(k, S) targets as floats; raises TargetOutOfRangeError for the first non-finite/out-of-range."""
        t = np.asarray(targets, dtype=np.float64)
        bad = ~(np.isfinite(t) & (t >= self._accept_lo) & (t <= self._accept_hi))
        if np.any(bad):
            row, col = np.unravel_index(int(np.argmax(bad)), bad.shape)
            s = self.servos[int(col)]
            raise TargetOutOfRangeError(s.role, float(t[row, col]), s.min_target, s.max_target, s.unit)
        return t

    def to_ticks(self, targets: ArrayLike) -> IntArray:
        """(k, S) targets -> (k, S) int64 goal ticks; all-or-nothing range check first."""
        t = self.check_targets(targets)
        return np.clip(round_ticks(self.forward(t)), self.min_tick, self.max_tick)

    def to_ticks_row(self, targets: FloatArray) -> IntArray:
        """`to_ticks` of one (S,) float row, as (S,): a control frame's path. The same elementwise
        arithmetic (knot count, gathers, Horner, rounding, clip) without the (k, S) broadcasting, and the
        same error for the first bad column."""
        t = targets
        ok = np.isfinite(t) & (t >= self._accept_lo) & (t <= self._accept_hi)
        if not np.logical_and.reduce(ok):  # (ufuncs called directly: no `any` / `clip` / `sum` wrappers)
            col = int(np.argmin(ok))  # the first bad column
            s = self.servos[col]
            raise TargetOutOfRangeError(s.role, float(t[col]), s.min_target, s.max_target, s.unit)
        ticks: IntArray = np.minimum(np.maximum(round_ticks(self.forward_row(t)), self.min_tick), self.max_tick)
        return ticks  # (np.clip of integers is this minimum of the maximum)

    def forward_row(self, targets: FloatArray) -> FloatArray:
        """`forward` of one (S,) row, as (S,) float ticks (the same elementwise arithmetic). Each piece's
        base and coefficients are gathered by one flat index with ``take`` (the same entries as `forward`'s
        two-index gathers, at a fraction of their cost)."""
        t = targets
        at = self._row_piece + np.add.reduce(t[:, None] >= self._knots, axis=-1)  # (the knot count, as `sum`)
        c0, c1, c2, c3 = self._flat_coef
        dx = t - self._flat_base.take(at)
        return np.asarray(c0.take(at) + dx * (c1.take(at) + dx * (c2.take(at) + dx * c3.take(at))), dtype=np.float64)

    def to_targets(self, ticks: ArrayLike, *, clip: bool = False) -> FloatArray:
        """(k, S) ticks -> (k, S) targets; refuses non-finite and (unless ``clip``) out-of-limit ticks."""
        k = np.asarray(ticks, dtype=np.float64)
        finite = np.isfinite(k)
        bad = ~finite if clip else ~(finite & (k >= self.min_tick) & (k <= self.max_tick))
        if np.any(bad):
            row, col = np.unravel_index(int(np.argmax(bad)), bad.shape)
            s = self.servos[int(col)]
            raise TickOutOfRangeError(s.role, float(k[row, col]), s.min_tick, s.max_tick)
        offset = np.clip(k, self.min_tick, self.max_tick) - self.min_tick
        whole = np.floor(offset)
        frac = offset - whole
        at = self._row_start + whole.astype(np.int64)
        lo = self._flat_table[at]
        if not np.any(frac):
            return np.asarray(lo, dtype=np.float64)
        return np.asarray(lo + frac * (self._flat_table[at + 1] - lo), dtype=np.float64)
