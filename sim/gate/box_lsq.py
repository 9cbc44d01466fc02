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

_CACHE_SETS = 1024  # free sets kept (a few kB each); a full cache starts afresh
_Blocks = tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.int64]]


class BoxLsq:
    """Primal active-set solver for a strictly convex box-constrained least squares (A full column rank)."""

    def __init__(self, a: FloatArray, lo: float, hi: float, max_iter: int = 200) -> None:
        self.a = np.asarray(a, dtype=np.float64)
        self.h = self.a.T @ self.a
        n = self.h.shape[0]
        self.lo = np.full(n, float(lo))
        self.hi = np.full(n, float(hi))
        self._lo, self._hi = float(lo), float(hi)
        self.max_iter = max_iter
        self._x = np.clip(np.zeros(n), self.lo, self.hi)
        self._free = np.ones(n, dtype=bool)
        self._cache: dict[bytes, _Blocks] = {}
        self._last_y: bytes | None = None  # the y of the last solve that returned (its answer is ``_x``)

    def _blocks(self, free: NDArray[np.bool_]) -> _Blocks:
        """inv(H_free,free), H_free,fixed and the free and fixed indices, cached per free set (the set
        rarely changes frame to frame)."""
        key = free.tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        fi, xi = np.flatnonzero(free), np.flatnonzero(~free)
        rows = self.h.take(fi, axis=0)  # the same entries as h[np.ix_(free, ...)], gathered
        h_ff = rows.take(fi, axis=1)
        blocks = (
            np.asarray(np.linalg.inv(h_ff), dtype=np.float64) if len(fi) else h_ff,
            rows.take(xi, axis=1),
            fi,
            xi,
        )
        if len(self._cache) >= _CACHE_SETS:
            self._cache.clear()
        self._cache[key] = blocks
        return blocks

    def solve(self, y: FloatArray) -> FloatArray | None:
        """The minimiser, or None if the iteration limit was hit (the caller then uses a reference solver).

        The same arithmetic as the plain active-set loop (`tests/sim/test_box_lsq.py` keeps it) on fewer,
        cheaper numpy calls: the bounds are one number each, the free and fixed sets are index lists
        gathered with ``take``. The answer to the y solved last is returned again without iterating: the
        loop started from its own answer redoes its last step bit for bit and stops there."""
        yv = np.asarray(y, dtype=np.float64)
        key = yv.tobytes()
        if key == self._last_y:
            return self._x.copy()
        self._last_y = None
        b = self.a.T @ yv
        h, lo, hi = self.h, self._lo, self._hi
        x = np.clip(self._x, lo, hi)
        free = self._free.copy()
        tol = 1e-12 * max(1.0, float(np.abs(b).max(initial=0.0)))
        for _ in range(self.max_iter):
            inv_ff, h_fx, fi, xi = self._blocks(free)
            if len(fi):
                xf = inv_ff @ (b.take(fi) - h_fx @ x.take(xi))
                if xf.min() < lo or xf.max() > hi:
                    cur = x.take(fi)
                    d = xf - cur
                    # distance to the bound ahead per free variable (inf where it does not move that way)
                    t_lo = np.divide(lo - cur, d, out=np.full(len(d), np.inf), where=d < 0)
                    t_hi = np.divide(hi - cur, d, out=np.full(len(d), np.inf), where=d > 0)
                    t = np.minimum(t_lo, t_hi)
                    k = int(np.argmin(t))
                    step = min(max(float(t[k]), 0.0), 1.0)
                    x[fi] = np.clip(cur + step * d, lo, hi)
                    idx = fi[k]
                    x[idx] = lo if d[k] < 0 else hi
                    free[idx] = False
                    continue
                x[fi] = xf
            # KKT on the fixed variables: the gradient must push each against its bound. Their violations
            # only (free ones count 0 and tol > 0): the same first largest one as over all variables
            if len(xi):
                g = (h @ x - b).take(xi)  # gradient / 2
                xx = x.take(xi)
                viol = np.where(xx <= lo, -g, 0.0) + np.where(xx >= hi, g, 0.0)
                w = int(np.argmax(viol))
                if not viol[w] <= tol:
                    free[xi[w]] = True
                    continue
            self._x, self._free = x.copy(), free.copy()
            self._last_y = key
            return x
        return None
