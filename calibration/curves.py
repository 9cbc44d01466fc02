"""One-input servo curves: actuator target (deg or mm) -> goal tick (float), and back.

Every curve is strictly monotone (increasing or decreasing) on the whole real line, checked at
construction, so it is invertible everywhere. Point curves (piecewise-linear, PCHIP) are defined by
measured ``(target, tick)`` points and continue past their end points as straight lines with the end
segment's secant slope. Limits, neutral and rounding to integer ticks belong to
:class:`servoface.calibration.servo.ServoCalibration`; a curve is pure math.

All evaluation is vectorised: ``forward`` and ``inverse`` take and return float arrays of any shape.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator
from servoface.calibration.errors import CurveError, NotMonotoneError

TICKS_PER_TURN = 4096
TICKS_PER_DEG = TICKS_PER_TURN / 360.0
CENTRE_TICK = 2048

FloatArray = NDArray[np.float64]


def as_points(points: ArrayLike, *, what: str = "points") -> FloatArray:
    """Validate measured points: a (k, 2) finite float array of (target, tick), k >= 2.

    Returns them sorted by target. Raises :class:`NotMonotoneError` when two points share a target or
    the ticks are not strictly monotone in the target (the message names both points).
    """
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise CurveError(f"{what}: expected a (k, 2) array of (target, tick) pairs, got shape {arr.shape}")
    if arr.shape[0] < 2:
        raise CurveError(f"{what}: expected at least 2 (target, tick) points, got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.argwhere(~np.isfinite(arr))[0][0])
        raise CurveError(f"{what}: point {bad} {arr[bad].tolist()} is not finite")
    order = np.argsort(arr[:, 0], kind="stable")
    arr = arr[order]
    d_target = np.diff(arr[:, 0])
    if np.any(d_target == 0.0):
        i = int(np.argwhere(d_target == 0.0)[0][0])
        raise NotMonotoneError(
            f"{what}: two points share the target {arr[i, 0]:g} (ticks {arr[i, 1]:g} and {arr[i + 1, 1]:g}); "
            "expected one tick per target"
        )
    d_tick = np.diff(arr[:, 1])
    sign = np.sign(d_tick[0])
    bad_idx = np.argwhere((np.sign(d_tick) != sign) | (d_tick == 0.0))
    if sign == 0.0 or bad_idx.size:
        i = int(bad_idx[0][0]) if bad_idx.size else 0
        direction = "increasing" if sign > 0 else "decreasing"
        raise NotMonotoneError(
            f"{what}: ticks are not strictly monotone in the target: ({arr[i, 0]:g}, {arr[i, 1]:g}) -> "
            f"({arr[i + 1, 0]:g}, {arr[i + 1, 1]:g}) breaks the {direction} order of the first points; "
            "expected every step to move the tick the same way"
        )
    return arr


class Curve(ABC):
    """A strictly monotone map target -> tick (float), invertible on the whole real line."""

    kind: ClassVar[str]

    @property
    @abstractmethod
    def increasing(self) -> bool:
        """True when the tick grows with the target."""

    @abstractmethod
    def forward(self, targets: ArrayLike) -> FloatArray:
        """Ticks (float, same shape) for targets in deg or mm."""

    @abstractmethod
    def inverse(self, ticks: ArrayLike) -> FloatArray:
        """Targets (same shape) for ticks; exact inverse of :meth:`forward` up to float rounding."""

    @abstractmethod
    def slope(self, targets: ArrayLike) -> FloatArray:
        """d tick / d target at targets (used to check resolution and for plots)."""

    @abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters, including ``"kind"``."""

    @abstractmethod
    def pieces(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The curve as polynomial pieces, for evaluating many curves at once (see servoface.calibration.bank).

        Returns ``knots`` (n,) ascending targets, ``base`` (n + 1,) and ``coef`` (n + 1, 4): for a target
        t with ``i = count(knots <= t)``, tick = sum_p coef[i, p] * (t - base[i]) ** p. Piece 0 is the
        straight continuation below the first knot, piece n the one above the last.
        """

    @property
    def points(self) -> FloatArray:
        """(k, 2) float: the (target, tick) points that define the curve; empty for parametric curves."""
        return np.zeros((0, 2))


class LinearCurve(Curve):
    """tick = offset_tick + direction * scale_tick_per_unit * target (direction = +1 or -1)."""

    kind: ClassVar[str] = "linear"

    def __init__(self, offset_tick: float, scale_tick_per_unit: float, direction: int = 1) -> None:
        if not (np.isfinite(offset_tick) and np.isfinite(scale_tick_per_unit)):
            raise CurveError(f"linear curve: offset {offset_tick!r} and scale {scale_tick_per_unit!r} must be finite")
        if scale_tick_per_unit <= 0.0:
            raise NotMonotoneError(
                f"linear curve: scale {scale_tick_per_unit!r} tick per unit must be > 0 "
                "(use direction = -1 for a reversed servo)"
            )
        if direction not in (1, -1):
            raise CurveError(f"linear curve: direction {direction!r} must be +1 or -1")
        self.offset_tick = float(offset_tick)
        self.scale_tick_per_unit = float(scale_tick_per_unit)
        self.direction = int(direction)
        self._gain = self.direction * self.scale_tick_per_unit

    @classmethod
    def fit(cls, points: ArrayLike) -> LinearCurve:
        """Least-squares line through measured (target, tick) points (strictly monotone, k >= 2)."""
        arr = as_points(points)
        gain, offset = np.polyfit(arr[:, 0], arr[:, 1], 1)
        if gain == 0.0 or not np.isfinite(gain):
            raise NotMonotoneError(f"linear fit: slope {gain!r} tick per unit; the points do not move the servo")
        return cls(float(offset), float(abs(gain)), 1 if gain > 0 else -1)

    @property
    def increasing(self) -> bool:
        return self.direction > 0

    def forward(self, targets: ArrayLike) -> FloatArray:
        return self.offset_tick + self._gain * np.asarray(targets, dtype=np.float64)

    def inverse(self, ticks: ArrayLike) -> FloatArray:
        return (np.asarray(ticks, dtype=np.float64) - self.offset_tick) / self._gain

    def slope(self, targets: ArrayLike) -> FloatArray:
        return np.full(np.shape(targets), self._gain)

    def pieces(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        coef = np.array([[self.offset_tick, self._gain, 0.0, 0.0]] * 2)
        return np.zeros(1), np.zeros(2), coef

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "offset_tick": self.offset_tick,
            "scale_tick_per_unit": self.scale_tick_per_unit,
            "direction": self.direction,
        }


class _PointCurve(Curve):
    """Shared part of curves through measured points: validation and straight-line continuation."""

    def __init__(self, points: ArrayLike) -> None:
        self._pts = as_points(points, what=f"{self.kind} curve points")
        x, y = self._pts[:, 0], self._pts[:, 1]
        self._x, self._y = x, y
        self._increasing = bool(y[-1] > y[0])
        with np.errstate(over="ignore"):
            secants = np.diff(y) / np.diff(x)
        if not np.all(np.isfinite(secants)):
            i = int(np.argmax(~np.isfinite(secants)))
            raise CurveError(
                f"{self.kind} curve points: targets {x[i]:g} and {x[i + 1]:g} are too close together for a "
                "finite slope; expected targets that differ by more than float rounding"
            )
        self._slope_lo, self._slope_hi = float(secants[0]), float(secants[-1])
        # ticks sorted ascending with their targets, for the inverse
        self._yx = (y, x) if self._increasing else (y[::-1], x[::-1])

    @property
    def increasing(self) -> bool:
        return self._increasing

    @property
    def points(self) -> FloatArray:
        return self._pts.copy()

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "points": self._pts.tolist()}

    @abstractmethod
    def _inner_coef(self) -> FloatArray:
        """(n - 1, 4) ascending-power coefficients of the pieces between the points."""

    def pieces(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        x, y = self._x, self._y
        below = [y[0], self._slope_lo, 0.0, 0.0]
        above = [y[-1], self._slope_hi, 0.0, 0.0]
        coef = np.vstack([below, self._inner_coef(), above])
        base = np.concatenate([[x[0]], x[:-1], [x[-1]]])
        return x.copy(), base, coef

    @abstractmethod
    def _inside(self, targets: FloatArray) -> FloatArray:
        """Forward on targets within [x[0], x[-1]]."""

    def forward(self, targets: ArrayLike) -> FloatArray:
        t = np.asarray(targets, dtype=np.float64)
        x, y = self._x, self._y
        out = self._inside(np.clip(t, x[0], x[-1]))
        out = np.where(t < x[0], y[0] + self._slope_lo * (t - x[0]), out)
        out = np.where(t > x[-1], y[-1] + self._slope_hi * (t - x[-1]), out)
        return np.asarray(out, dtype=np.float64)

    def _outside_inverse(self, ticks: FloatArray, inside: FloatArray) -> FloatArray:
        x, y = self._x, self._y
        below = (ticks - y[0]) / self._slope_lo + x[0]
        above = (ticks - y[-1]) / self._slope_hi + x[-1]
        if self._increasing:
            out = np.where(ticks < y[0], below, inside)
            return np.asarray(np.where(ticks > y[-1], above, out), dtype=np.float64)
        out = np.where(ticks > y[0], below, inside)
        return np.asarray(np.where(ticks < y[-1], above, out), dtype=np.float64)


class PiecewiseLinearCurve(_PointCurve):
    """Straight segments between measured (target, tick) points."""

    kind: ClassVar[str] = "piecewise_linear"

    def _inside(self, targets: FloatArray) -> FloatArray:
        return np.asarray(np.interp(targets, self._x, self._y), dtype=np.float64)

    def _inner_coef(self) -> FloatArray:
        slopes = np.diff(self._y) / np.diff(self._x)
        zeros = np.zeros_like(slopes)
        return np.stack([self._y[:-1], slopes, zeros, zeros], axis=1)

    def inverse(self, ticks: ArrayLike) -> FloatArray:
        k = np.asarray(ticks, dtype=np.float64)
        ys, xs = self._yx
        inside = np.asarray(np.interp(k, ys, xs), dtype=np.float64)
        return self._outside_inverse(k, inside)

    def slope(self, targets: ArrayLike) -> FloatArray:
        t = np.asarray(targets, dtype=np.float64)
        seg_slopes = np.diff(self._y) / np.diff(self._x)
        idx = np.clip(np.searchsorted(self._x, t, side="right") - 1, 0, len(seg_slopes) - 1)
        return np.asarray(seg_slopes[idx], dtype=np.float64)


class PchipCurve(_PointCurve):
    """Monotone cubic (PCHIP, Fritsch-Carlson) through measured (target, tick) points.

    PCHIP keeps monotone data monotone by construction; each end slope is kept within 0.5..3 times the
    end secant (scipy's one-sided estimate can be 0: a flat end). The inverse starts from a dense
    monotone table (64 samples per segment) and polishes with safeguarded Newton steps, so it is exact
    to float rounding and vectorised.
    """

    kind: ClassVar[str] = "pchip"
    _SAMPLES_PER_SEGMENT: ClassVar[int] = 64

    def __init__(self, points: ArrayLike) -> None:
        super().__init__(points)
        # PCHIP's slopes, with each end slope kept within [0.5, 3] x its end secant (scipy's one-sided
        # estimate may be 0 or nearly): still monotone (inside the Fritsch-Carlson box), never flat at an
        # end, so every target has a finite resolution and the inverse stays well conditioned.
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            try:
                slopes = np.asarray(PchipInterpolator(self._x, self._y).derivative()(self._x), dtype=np.float64)
            except ValueError:  # scipy refuses the slopes it computed: not finite
                slopes = np.full(self._x.shape, np.inf)
            for i, secant in ((0, self._slope_lo), (-1, self._slope_hi)):
                ratio = slopes[i] / secant
                slopes[i] = secant * min(max(ratio, 0.5), 3.0)
        if not np.all(np.isfinite(slopes)):
            raise CurveError(
                f"pchip curve: points {self._x[0]:g}..{self._x[-1]:g} are too close together for a finite "
                "slope; expected targets that differ by more than float rounding"
            )
        self._spline = CubicHermiteSpline(self._x, self._y, slopes, extrapolate=True)
        self._dspline = self._spline.derivative()
        n = self._SAMPLES_PER_SEGMENT
        grid = np.concatenate(
            [np.linspace(a, b, n, endpoint=False) for a, b in zip(self._x[:-1], self._x[1:], strict=True)]
            + [self._x[-1:]]
        )
        table = np.asarray(self._spline(grid), dtype=np.float64)
        steps = np.diff(table)
        if not (np.all(steps > 0.0) or np.all(steps < 0.0)):
            i = int(np.argwhere((steps <= 0.0) if self._increasing else (steps >= 0.0))[0][0])
            raise NotMonotoneError(
                f"pchip curve: not strictly monotone near target {grid[i]:g} (ticks {table[i]:g} -> {table[i + 1]:g})"
            )
        self._grid = grid
        self._table = table if self._increasing else table[::-1]
        self._grid_sorted = grid if self._increasing else grid[::-1]

    def _inside(self, targets: FloatArray) -> FloatArray:
        return np.asarray(self._spline(targets), dtype=np.float64)

    def _inner_coef(self) -> FloatArray:
        return np.asarray(self._spline.c[::-1].T, dtype=np.float64)  # scipy: highest power first

    def inverse(self, ticks: ArrayLike) -> FloatArray:
        k = np.asarray(ticks, dtype=np.float64)
        table, grid = self._table, self._grid_sorted
        kc = np.clip(k, table[0], table[-1])
        # bracket [lo, hi] in target from the table, start from linear interpolation inside it
        j = np.clip(np.searchsorted(table, kc, side="right") - 1, 0, len(table) - 2)
        lo_t, hi_t = grid[j], grid[j + 1]
        lo, hi = np.minimum(lo_t, hi_t), np.maximum(lo_t, hi_t)
        x = np.asarray(np.interp(kc, table, grid), dtype=np.float64)
        for _ in range(3):
            f = self._spline(x) - kc
            d = self._dspline(x)
            step = np.divide(f, d, out=np.zeros_like(f), where=np.abs(d) > 1e-12)
            x = np.clip(x - step, lo, hi)
        return self._outside_inverse(k, x)

    def slope(self, targets: ArrayLike) -> FloatArray:
        t = np.asarray(targets, dtype=np.float64)
        inside = np.asarray(self._dspline(np.clip(t, self._x[0], self._x[-1])), dtype=np.float64)
        inside = np.where(t < self._x[0], self._slope_lo, inside)
        return np.asarray(np.where(t > self._x[-1], self._slope_hi, inside), dtype=np.float64)


CURVE_KINDS: dict[str, type[Curve]] = {
    LinearCurve.kind: LinearCurve,
    PiecewiseLinearCurve.kind: PiecewiseLinearCurve,
    PchipCurve.kind: PchipCurve,
}


def fit_curve(kind: str, points: ArrayLike) -> Curve:
    """Build a curve of ``kind`` ("linear", "piecewise_linear", "pchip") from measured points."""
    if kind == LinearCurve.kind:
        return LinearCurve.fit(points)
    if kind == PiecewiseLinearCurve.kind:
        return PiecewiseLinearCurve(points)
    if kind == PchipCurve.kind:
        return PchipCurve(points)
    raise CurveError(f"unknown curve kind {kind!r}; expected one of {sorted(CURVE_KINDS)}")


def points_list(points: Sequence[tuple[float, float]] | FloatArray) -> list[list[float]]:
    """Plain nested lists of (target, tick) for JSON."""
    return [[float(a), float(b)] for a, b in np.asarray(points, dtype=np.float64).reshape(-1, 2)]
