"""Curves: strict monotonicity at construction, exact inverses, straight-line continuation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.calibration.curves import LinearCurve, PchipCurve, PiecewiseLinearCurve, as_points, fit_curve
from servoface.calibration.errors import CurveError, NotMonotoneError


@st.composite
def monotone_points(draw: st.DrawFn) -> np.ndarray:
    """3..12 strictly monotone (target, tick) points with ticks inside 0..4095."""
    k = draw(st.integers(3, 12))
    steps_t = draw(st.lists(st.floats(0.2, 10.0), min_size=k - 1, max_size=k - 1))
    steps_k = draw(st.lists(st.floats(2.0, 200.0), min_size=k - 1, max_size=k - 1))
    t0 = draw(st.floats(-40.0, 10.0))
    sign = draw(st.sampled_from([1.0, -1.0]))
    targets = t0 + np.concatenate([[0.0], np.cumsum(steps_t)])
    ticks = 2048.0 + sign * (np.concatenate([[0.0], np.cumsum(steps_k)]) - sum(steps_k) / 2)
    return np.stack([targets, ticks], axis=1)


@pytest.mark.parametrize("cls", [PiecewiseLinearCurve, PchipCurve])
@settings(max_examples=40, deadline=None)
@given(pts=monotone_points(), frac=st.lists(st.floats(-0.2, 1.2), min_size=1, max_size=20))
def test_point_curves_invert_exactly_and_pass_through_points(
    cls: type[PchipCurve], pts: np.ndarray, frac: list[float]
) -> None:
    curve = cls(pts)
    assert np.allclose(curve.forward(pts[:, 0]), pts[:, 1], atol=1e-9)
    lo, hi = pts[0, 0], pts[-1, 0]
    t = lo + np.asarray(frac) * (hi - lo)  # includes the straight continuation beyond the points
    assert np.allclose(curve.inverse(curve.forward(t)), t, atol=1e-7 * max(1.0, hi - lo))
    dense = curve.forward(np.linspace(lo - 1, hi + 1, 2000))
    steps = np.diff(dense)
    assert np.all(steps > 0) if curve.increasing else np.all(steps < 0)


@settings(max_examples=40, deadline=None)
@given(
    offset=st.floats(0, 4095),
    scale=st.floats(0.5, 60),
    direction=st.sampled_from([1, -1]),
    t=st.floats(-100, 100),
)
def test_linear_curve_inverts(offset: float, scale: float, direction: int, t: float) -> None:
    curve = LinearCurve(offset, scale, direction)
    assert curve.inverse(curve.forward(t)) == pytest.approx(t, abs=1e-9)
    assert curve.increasing == (direction > 0)


def test_linear_fit_recovers_offset_scale_direction() -> None:
    t = np.array([-10.0, 0.0, 5.0, 20.0])
    curve = LinearCurve.fit(np.stack([t, 2048 - 11.377 * t], axis=1))
    assert curve.direction == -1
    assert curve.scale_tick_per_unit == pytest.approx(11.377)
    assert curve.offset_tick == pytest.approx(2048)


@pytest.mark.parametrize("kind", ["linear", "piecewise_linear", "pchip"])
@pytest.mark.parametrize(
    "bad, message",
    [
        ([[0, 2000], [1, 2100], [2, 2050]], "not strictly monotone"),  # goes back
        ([[0, 2000], [1, 2100], [2, 2100]], "not strictly monotone"),  # flat step
        ([[0, 2000], [0, 2100], [2, 2200]], "share the target"),  # two ticks for one target
    ],
)
def test_monotonicity_check_rejects_bad_points(kind: str, bad: list[list[float]], message: str) -> None:
    with pytest.raises(NotMonotoneError, match=message):
        fit_curve(kind, bad)


def test_points_must_be_finite_pairs() -> None:
    with pytest.raises(CurveError, match="not finite"):
        as_points([[0, 2000], [float("nan"), 2100]])
    with pytest.raises(CurveError, match=r"\(k, 2\)"):
        as_points([[0, 2000, 1], [1, 2100, 1]])
    with pytest.raises(CurveError, match="at least 2"):
        as_points([[0, 2000]])
    with pytest.raises(NotMonotoneError):
        LinearCurve(2048, 0.0)
    with pytest.raises(CurveError, match="unknown curve kind"):
        fit_curve("cubic", [[0, 1], [1, 2]])


def test_pchip_stays_monotone_where_a_plain_cubic_overshoots() -> None:
    pts = np.array([[0, 2048], [1, 2049], [2, 2050], [3, 2400], [4, 2401]], dtype=float)
    curve = PchipCurve(pts)
    dense = curve.forward(np.linspace(0, 4, 4001))
    assert np.all(np.diff(dense) > 0)
    assert dense.min() >= 2048 - 1e-9 and dense.max() <= 2401 + 1e-9
