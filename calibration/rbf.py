"""Radial-basis maps for targets that depend on several inputs (Hardy multiquadric + affine term).

After Fratarcangeli 2008 §3.4 (see /work/shared/reference/muscle-models.md §4):

    G(P) = sum_i h_i * sqrt(|P - P_i|^2 + r_i^2) + a . [P, 1]

with per-centre stiffness radius r_i = distance from P_i to its nearest other centre, and the side
conditions sum h_i = sum h_i P_i = 0. The (k + d + 1) system is not symmetric when the r_i differ, so it
is solved by LU. An optional ``smoothing`` (ridge on the diagonal) turns exact interpolation into a
smoothing fit for noisy measurements.

Used for a skin anchor whose pull depends on its own servo and a neighbour: inputs are the ticks of
(own servo, neighbours...), the output is the pull in mm. The servo tick for a wanted pull, given the
neighbours' ticks, is found by 1-D root finding along the own-servo axis (:meth:`RbfMap.solve_axis`),
after checking that the map is strictly monotone along that line.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray
from servoface.calibration.errors import CurveError, NotMonotoneError

FloatArray = NDArray[np.float64]

_MONOTONE_SAMPLES = 33
_BISECTION_STEPS = 52


class RbfMap:
    """A fitted map R^d -> R. Build with :meth:`fit`; evaluate with :meth:`evaluate`."""

    def __init__(
        self,
        centres: FloatArray,
        radii: FloatArray,
        weights: FloatArray,
        affine: FloatArray,
        shift: FloatArray,
        scale: float,
        values: FloatArray,
        smoothing: float,
    ) -> None:
        self._centres = centres  # (k, d), normalised
        self._radii = radii  # (k,)
        self._weights = weights  # (k,)
        self._affine = affine  # (d + 1,)
        self._shift = shift  # (d,)
        self._scale = scale
        self._values = values  # (k,) the fitted outputs
        self.smoothing = smoothing

    @classmethod
    def fit(cls, inputs: ArrayLike, outputs: ArrayLike, *, smoothing: float = 0.0) -> RbfMap:
        """Fit G with G(inputs[i]) = outputs[i] (exactly when smoothing = 0).

        inputs: (k, d) float, k >= d + 2 distinct points not all on one hyperplane.
        outputs: (k,) float.
        """
        p = np.asarray(inputs, dtype=np.float64)
        q = np.asarray(outputs, dtype=np.float64)
        if p.ndim != 2 or p.shape[0] == 0 or p.shape[1] == 0:
            raise CurveError(f"rbf fit: inputs must be a (k, d) array, got shape {p.shape}")
        k, d = p.shape
        if q.shape != (k,):
            raise CurveError(f"rbf fit: outputs must have shape ({k},) to match the inputs, got {q.shape}")
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
            raise CurveError("rbf fit: inputs and outputs must be finite")
        if k < d + 2:
            raise CurveError(f"rbf fit: {k} points for {d} inputs; expected at least {d + 2}")
        if not (np.isfinite(smoothing) and smoothing >= 0.0):
            raise CurveError(f"rbf fit: smoothing {smoothing!r} must be >= 0")
        # one shift/scale for all dimensions keeps the metric (multiquadric is scale-equivariant)
        shift = p.mean(axis=0)
        scale = float(np.max(np.abs(p - shift))) or 1.0
        pn = (p - shift) / scale
        dist = np.sqrt(((pn[:, None, :] - pn[None, :, :]) ** 2).sum(axis=-1))
        off = dist + np.diag(np.full(k, np.inf))
        radii = off.min(axis=1)
        if np.any(radii == 0.0):
            i = int(np.argmin(radii))
            j = int(np.argmin(off[i]))
            raise CurveError(f"rbf fit: input points {i} and {j} are identical ({p[i].tolist()})")
        phi = np.sqrt(dist**2 + radii[None, :] ** 2)  # phi[j, i] = R_i(P_j)
        poly = np.hstack([pn, np.ones((k, 1))])
        system = np.zeros((k + d + 1, k + d + 1))
        system[:k, :k] = phi + smoothing * np.eye(k)
        system[:k, k:] = poly
        system[k:, :k] = poly.T
        rhs = np.concatenate([q, np.zeros(d + 1)])
        try:
            lu = scipy.linalg.lu_factor(system, check_finite=False)
            sol = scipy.linalg.lu_solve(lu, rhs, check_finite=False)
        except (scipy.linalg.LinAlgError, ValueError) as err:
            raise CurveError(f"rbf fit: the system is singular ({err})") from err
        if not np.all(np.isfinite(sol)) or np.linalg.cond(system) > 1e14:
            raise CurveError("rbf fit: the system is singular; the input points must not all lie on one line/plane")
        return cls(pn, radii, sol[:k], sol[k:], shift, scale, q.copy(), float(smoothing))

    @property
    def dims(self) -> int:
        return int(self._centres.shape[1])

    @property
    def inputs(self) -> FloatArray:
        """(k, d) float: the fitted input points (in the caller's units)."""
        return self._centres * self._scale + self._shift

    @property
    def outputs(self) -> FloatArray:
        """(k,) float: the fitted outputs."""
        return self._values.copy()

    def evaluate(self, points: ArrayLike) -> FloatArray:
        """G at points: (n, d) -> (n,), or (d,) -> () ."""
        p = np.asarray(points, dtype=np.float64)
        single = p.ndim == 1
        p2 = np.atleast_2d(p)
        if p2.shape[-1] != self.dims:
            raise CurveError(f"rbf evaluate: expected points with {self.dims} inputs, got shape {p.shape}")
        pn = (p2 - self._shift) / self._scale
        d2 = ((pn[:, None, :] - self._centres[None, :, :]) ** 2).sum(axis=-1)
        out = np.sqrt(d2 + self._radii[None, :] ** 2) @ self._weights
        out = out + pn @ self._affine[:-1] + self._affine[-1]
        return np.asarray(out[0] if single else out, dtype=np.float64)

    def axis_direction(self, points: ArrayLike, axis: int, lo: float, hi: float) -> FloatArray:
        """+1 / -1 per row when G is strictly increasing / decreasing along ``axis`` on [lo, hi], else 0.

        points: (n, d); the value in column ``axis`` is ignored. Checked on 33 samples per row.
        """
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        n = p.shape[0]
        s = np.linspace(lo, hi, _MONOTONE_SAMPLES)
        grid = np.repeat(p, _MONOTONE_SAMPLES, axis=0)
        grid[:, axis] = np.tile(s, n)
        values = self.evaluate(grid).reshape(n, _MONOTONE_SAMPLES)
        steps = np.diff(values, axis=1)
        inc = np.all(steps > 0.0, axis=1)
        dec = np.all(steps < 0.0, axis=1)
        return np.where(inc, 1.0, np.where(dec, -1.0, 0.0))

    def solve_axis(self, outputs: ArrayLike, points: ArrayLike, axis: int, lo: float, hi: float) -> FloatArray:
        """The value along ``axis`` in [lo, hi] where G equals ``outputs``, the other inputs held.

        outputs: (n,) or scalar; points: (n, d) or (d,) (column ``axis`` ignored). Vectorised bisection
        after a monotonicity check along the line; raises :class:`NotMonotoneError` when G is not strictly
        monotone there and :class:`CurveError` when an output is not reachable on [lo, hi].
        """
        out = np.atleast_1d(np.asarray(outputs, dtype=np.float64))
        p = np.atleast_2d(np.asarray(points, dtype=np.float64)).copy()
        if p.shape[0] == 1 and out.shape[0] > 1:
            p = np.repeat(p, out.shape[0], axis=0)
        if p.shape[0] != out.shape[0]:
            raise CurveError(f"rbf solve: {out.shape[0]} outputs for {p.shape[0]} points")
        if not (0 <= axis < self.dims) or not (lo < hi):
            raise CurveError(f"rbf solve: bad axis {axis} or interval [{lo}, {hi}]")
        direction = self.axis_direction(p, axis, lo, hi)
        if np.any(direction == 0.0):
            i = int(np.argmax(direction == 0.0))
            raise NotMonotoneError(
                f"rbf map is not strictly monotone along input {axis} on [{lo:g}, {hi:g}] "
                f"with the other inputs at {np.delete(p[i], axis).tolist()}"
            )
        p[:, axis] = lo
        g_lo = self.evaluate(p)
        p[:, axis] = hi
        g_hi = self.evaluate(p)
        reach_lo, reach_hi = np.minimum(g_lo, g_hi), np.maximum(g_lo, g_hi)
        bad = ~((out >= reach_lo) & (out <= reach_hi))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise CurveError(
                f"rbf map: output {out[i]:g} is not reachable along input {axis} on [{lo:g}, {hi:g}] "
                f"(reachable {reach_lo[i]:g}..{reach_hi[i]:g}) with the other inputs at "
                f"{np.delete(p[i], axis).tolist()}"
            )
        a = np.full(out.shape, float(lo))
        b = np.full(out.shape, float(hi))
        for _ in range(_BISECTION_STEPS):
            mid = 0.5 * (a + b)
            p[:, axis] = mid
            below = (self.evaluate(p) - out) * direction < 0.0
            a = np.where(below, mid, a)
            b = np.where(below, b, mid)
        return np.asarray(0.5 * (a + b), dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """Measured data and settings; the coefficients are refitted on load (deterministic)."""
        return {
            "kind": "rbf_multiquadric",
            "inputs": self.inputs.tolist(),
            "outputs": self._values.tolist(),
            "smoothing": self.smoothing,
        }
