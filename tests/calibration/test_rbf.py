"""Hardy multiquadric RBF maps: exact fit, affine precision, inversion along one axis, refusals."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.calibration.errors import CurveError, NotMonotoneError
from servoface.calibration.rbf import RbfMap


def _anchor_data(n: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Pull (mm) of an anchor vs (own tick, neighbour tick): crank pull minus a neighbour drag."""
    own, nb = np.meshgrid(np.linspace(1800, 2600, n), np.linspace(1900, 2300, n), indexing="ij")
    x = np.stack([own.ravel(), nb.ravel()], axis=1)
    y = 8 * np.sin((x[:, 0] - 2048) / 4096 * 2 * np.pi) - 0.004 * (x[:, 1] - 2048)
    return x, y


def test_fit_is_exact_at_the_centres_and_smooth_between() -> None:
    x, y = _anchor_data()
    rbf = RbfMap.fit(x, y)
    assert np.allclose(rbf.evaluate(x), y, atol=1e-8)
    q = np.array([[2100.0, 2000.0], [2400.0, 2250.0]])
    truth = 8 * np.sin((q[:, 0] - 2048) / 4096 * 2 * np.pi) - 0.004 * (q[:, 1] - 2048)
    assert np.allclose(rbf.evaluate(q), truth, atol=0.05)
    assert rbf.evaluate(q[0]).shape == ()


def test_a_purely_affine_map_gets_zero_radial_weights() -> None:
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 100, size=(12, 3))
    y = 0.5 * x[:, 0] - 2 * x[:, 1] + 0.1 * x[:, 2] + 7
    rbf = RbfMap.fit(x, y)
    assert np.allclose(rbf._weights, 0.0, atol=1e-9)
    z = rng.uniform(0, 100, (5, 3))
    assert np.allclose(rbf.evaluate(z), 0.5 * z[:, 0] - 2 * z[:, 1] + 0.1 * z[:, 2] + 7, atol=1e-8)


@settings(max_examples=40, deadline=None)
@given(own=st.floats(1800, 2600), nb=st.floats(1900, 2300))
def test_solve_axis_inverts_along_the_own_servo(own: float, nb: float) -> None:
    x, y = _anchor_data()
    rbf = RbfMap.fit(x, y)
    pull = float(rbf.evaluate(np.array([own, nb])))
    tick = rbf.solve_axis(pull, [0.0, nb], axis=0, lo=1800, hi=2600)
    assert tick[0] == pytest.approx(own, abs=1e-6)


def test_solve_axis_refuses_non_monotone_lines_and_unreachable_outputs() -> None:
    t = np.linspace(-1, 1, 9)
    x = np.stack(np.meshgrid(t, t, indexing="ij"), axis=-1).reshape(-1, 2)
    rbf = RbfMap.fit(x, x[:, 0] ** 2 + x[:, 1])  # a valley along axis 0
    with pytest.raises(NotMonotoneError, match="not strictly monotone along input 0"):
        rbf.solve_axis(0.5, [0.0, 0.0], axis=0, lo=-1, hi=1)
    assert rbf.solve_axis(0.25, [0.0, 0.0], axis=0, lo=0, hi=1)[0] == pytest.approx(0.5, abs=0.02)
    with pytest.raises(CurveError, match="not reachable"):
        rbf.solve_axis(5.0, [0.0, 0.0], axis=0, lo=0, hi=1)


@pytest.mark.parametrize(
    "inputs, outputs, message",
    [
        ([[0, 0], [1, 0], [0, 1], [0, 0]], [1, 2, 3, 4], "identical"),
        ([[0, 0], [1, 0], [0, 1]], [1, 2, 3], "at least 4"),
        ([[0, 0], [1, 1], [2, 2], [3, 3]], [1, 2, 3, 4], "singular"),
        ([[0, 0], [1, 0], [0, 1], [1, 1]], [1, 2, float("nan"), 4], "finite"),
        ([[0, 0], [1, 0], [0, 1], [1, 1]], [1, 2, 3], "shape"),
    ],
)
def test_fit_refuses_bad_data(inputs: list[list[float]], outputs: list[float], message: str) -> None:
    with pytest.raises(CurveError, match=message):
        RbfMap.fit(inputs, outputs)


def test_smoothing_gives_up_exactness_but_stays_close() -> None:
    x, y = _anchor_data()
    noisy = y + np.random.default_rng(2).normal(0, 0.05, y.shape)
    exact = RbfMap.fit(x, noisy)
    smooth = RbfMap.fit(x, noisy, smoothing=1e-3)
    assert np.allclose(exact.evaluate(x), noisy, atol=1e-8)
    assert not np.allclose(smooth.evaluate(x), noisy, atol=1e-4)
    assert np.abs(smooth.evaluate(x) - y).mean() < 2 * np.abs(noisy - y).mean()
