"""A small warm-started box-constrained least-squares solver: min |A x - y|^2, lo <= x <= hi.

The face model fits muscle contractions to anchor pulls with this problem (A = [L; mu I], full column
rank, so the minimiser is unique) through scipy's NNLS/BVLS, about a millisecond a call. Between control
frames the set of contractions sitting at a bound rarely changes, so a primal active-set method started
from the previous frame's solution needs one or two small solves: tens of microseconds, same answer.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class BoxLsq:
    """Primal active-set solver for a strictly convex box-constrained least squares (A full column rank)."""

    def __init__(self, a: FloatArray, lo: float, hi: float, max_iter: int = 200) -> None:
        self.a = np.asarray(a, dtype=np.float64)
        self.h = self.a.T @ self.a
        n = self.h.shape[0]
        self.lo = np.full(n, float(lo))
        self.hi = np.full(n, float(hi))
        self.max_iter = max_iter
        self._x = np.clip(np.zeros(n), self.lo, self.hi)
        self._free = np.ones(n, dtype=bool)
        self._cache: dict[bytes, tuple[FloatArray, FloatArray]] = {}

    def _blocks(self, free: NDArray[np.bool_], fixed: NDArray[np.bool_]) -> tuple[FloatArray, FloatArray]:
        """inv(H_free,free) and H_free,fixed, cached per free set (the set rarely changes frame to frame)."""
        key = free.tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        blocks = (
            np.asarray(np.linalg.inv(self.h[np.ix_(free, free)]), dtype=np.float64),
            np.asarray(self.h[np.ix_(free, fixed)], dtype=np.float64),
        )
        if len(self._cache) > 256:
            self._cache.clear()
        self._cache[key] = blocks
        return blocks

    def solve(self, y: FloatArray) -> FloatArray | None:
        """The minimiser, or None if the iteration limit was hit (the caller then uses a reference solver)."""
        b = self.a.T @ np.asarray(y, dtype=np.float64)
        h, lo, hi = self.h, self.lo, self.hi
        x = np.clip(self._x, lo, hi)
        free = self._free.copy()
        free &= ~((x <= lo) | (x >= hi)) | self._free  # keep the warm start's free set
        tol = 1e-12 * max(1.0, float(np.abs(b).max(initial=0.0)))
        for _ in range(self.max_iter):
            fixed = ~free
            if free.any():
                inv_ff, h_fx = self._blocks(free, fixed)
                xf = inv_ff @ (b[free] - h_fx @ x[fixed])
                cur = x[free]
                out = (xf < lo[free]) | (xf > hi[free])
                if out.any():
                    d = xf - cur
                    with np.errstate(divide="ignore", invalid="ignore"):
                        t_lo = np.where(d < 0, (lo[free] - cur) / d, np.inf)
                        t_hi = np.where(d > 0, (hi[free] - cur) / d, np.inf)
                    t = np.minimum(t_lo, t_hi)
                    k = int(np.argmin(t))
                    step = float(np.clip(t[k], 0.0, 1.0))
                    x[free] = np.clip(cur + step * d, lo[free], hi[free])
                    idx = np.flatnonzero(free)[k]
                    x[idx] = lo[idx] if d[k] < 0 else hi[idx]
                    free[idx] = False
                    continue
                x[free] = xf
            g = h @ x - b  # gradient / 2
            at_lo = ~free & (x <= lo)
            at_hi = ~free & (x >= hi)
            viol = np.where(at_lo, -g, 0.0) + np.where(at_hi, g, 0.0)
            j = int(np.argmax(viol))
            if viol[j] <= tol:
                self._x, self._free = x.copy(), free.copy()
                return x
            free[j] = True
        return None
