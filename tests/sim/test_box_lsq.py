"""`BoxLsq.solve` (index gathers, scalar bounds, KKT on the fixed variables only, the last answer again
for the same y) returns bit for bit what the plain active-set loop returns, and leaves the same warm
start, on seeded random problems and on both built-in heads' face-model fits."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray
from servoface.sim.gate.box_lsq import BoxLsq

FloatArray = NDArray[np.float64]


class PlainBoxLsq:
    """The straightforward loop (boolean masks, bound arrays, violations over every variable): the
    reference `BoxLsq` must match."""

    def __init__(self, a: FloatArray, lo: float, hi: float, max_iter: int = 200) -> None:
        self.a = np.asarray(a, dtype=np.float64)
        self.h = self.a.T @ self.a
        n = self.h.shape[0]
        self.lo = np.full(n, float(lo))
        self.hi = np.full(n, float(hi))
        self.max_iter = max_iter
        self._x = np.clip(np.zeros(n), self.lo, self.hi)
        self._free = np.ones(n, dtype=bool)

    def solve(self, y: FloatArray) -> FloatArray | None:
        b = self.a.T @ np.asarray(y, dtype=np.float64)
        h, lo, hi = self.h, self.lo, self.hi
        x = np.clip(self._x, lo, hi)
        free = self._free.copy()
        free &= ~((x <= lo) | (x >= hi)) | self._free
        tol = 1e-12 * max(1.0, float(np.abs(b).max(initial=0.0)))
        for _ in range(self.max_iter):
            fixed = ~free
            if free.any():
                inv_ff = np.linalg.inv(self.h[np.ix_(free, free)])
                h_fx = self.h[np.ix_(free, fixed)]
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
            g = h @ x - b
            at_lo = ~free & (x <= lo)
            at_hi = ~free & (x >= hi)
            viol = np.where(at_lo, -g, 0.0) + np.where(at_hi, g, 0.0)
            j = int(np.argmax(viol))
            if viol[j] <= tol:
                self._x, self._free = x.copy(), free.copy()
                return x
            free[j] = True
        return None


def _same(a: FloatArray | None, b: FloatArray | None) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and a.tobytes() == b.tobytes())


def _run(a: FloatArray, lo: float, hi: float, ys: list[FloatArray], max_iter: int = 200) -> int:
    """Solve ``ys`` in order with both; asserts equal answers and warm starts, returns how many solves
    iterated into a bound (so a test can check its problems exercise the active set)."""
    fast, plain = BoxLsq(a, lo, hi, max_iter), PlainBoxLsq(a, lo, hi, max_iter)
    bounded = 0
    for k, y in enumerate(ys):
        got, want = fast.solve(y), plain.solve(y)
        assert _same(got, want), k
        assert np.array_equal(fast._free, plain._free) and fast._x.tobytes() == plain._x.tobytes(), k
        bounded += int(want is not None and not plain._free.all())
    return bounded


def _sequence(rng: np.random.Generator, n_y: int, count: int, scale: float) -> list[FloatArray]:
    """Random walks with jumps, repeats (the same y again, also after another) and returns to old ys."""
    ys: list[FloatArray] = []
    y = np.zeros(n_y)
    for k in range(count):
        r = rng.random()
        if ys and r < 0.15:
            ys.append(ys[-1].copy())
        elif len(ys) > 2 and r < 0.25:
            ys.append(ys[int(rng.integers(0, len(ys)))].copy())
        else:
            y = rng.uniform(-scale, scale, n_y) if k % 12 == 0 else y + rng.normal(0, scale / 8, n_y)
            ys.append(y.copy())
    return ys


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fast_solve_matches_the_plain_loop_on_random_problems(seed: int) -> None:
    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(4, 30)), int(rng.integers(2, 20))
    a = np.vstack([rng.normal(size=(m, n)), 0.1 * np.eye(n)])
    ys = [np.r_[y, np.zeros(n)] for y in _sequence(rng, m, 300, 3.0)]
    assert _run(a, -0.5, 1.5, ys) > 20
    assert _run(a, 0.0, 1.0, ys) > 20


def test_iteration_limit_gives_none_alike() -> None:
    rng = np.random.default_rng(5)
    a = np.vstack([rng.normal(size=(20, 12)), 0.1 * np.eye(12)])
    ys = [np.r_[y, np.zeros(12)] for y in _sequence(rng, 20, 120, 4.0)]
    _run(a, 0.0, 1.0, ys, max_iter=2)


@pytest.mark.parametrize("name", ["human", "dog"])
def test_fast_solve_matches_the_plain_loop_on_the_heads_fits(name: str) -> None:
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head

    fit: Any = FaceModel(load_head(name)).fit
    n_anchor, n_muscle = fit.unit_pull.shape
    a = np.vstack([fit.unit_pull, float(fit.mu) * np.eye(n_muscle)])
    rng = np.random.default_rng(7)
    ys = [np.r_[p, np.zeros(n_muscle)] for p in _sequence(rng, n_anchor, 400, 8.0)]
    bounded = _run(a, float(fit.low), float(fit.high), ys)
    assert bounded > 0 or name == "dog"  # the dog's contractions stay inside their range
