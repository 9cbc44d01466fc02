"""From measured (target, tick) points and a servo spec to a checked :class:`ServoCalibration`.

Shared by the interactive procedure, the CSV mode and the built-in generator, so every path runs the
same checks: strict monotonicity, coverage of the spec's range, residuals, tick limits inside 0..4095.
Expected imperfections (sparse points, large residuals) are warnings with numbers; data that cannot give
a safe curve is an error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from servoface.calibration.curves import Curve, as_points, fit_curve
from servoface.calibration.errors import CalibrationError, CoverageError, NotMonotoneError
from servoface.calibration.rbf import RbfMap
from servoface.calibration.servo import (
    MAX_POSITION_TICK,
    MIN_POSITION_TICK,
    RbfCoupling,
    ServoCalibration,
    round_ticks,
)
from servoface.calibration.spec import ServoSpec

COVERAGE_TOLERANCE = 0.02  # fraction of the range the points may stop short of each end
GAP_WARNING = 0.35  # warn when two neighbouring points are further apart than this fraction of the range
RESIDUAL_WARNING_TICK = 4.0  # warn when a fitted curve misses a measured point by more than this
FAR_OUTSIDE_RANGES = 1.0  # a point more than this many range widths past either end is refused (a typo)


@dataclass
class FitReport:
    """A fitted servo and what the checks found (``warnings`` are human-readable, with numbers)."""

    servo: ServoCalibration
    max_residual_tick: float
    warnings: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class EndTicks:
    """The goal ticks a curve puts the two ends of a servo's range at, rounded as every goal is: the tick
    limits of the calibration, refused unless both lie in ``MIN_POSITION_TICK..MAX_POSITION_TICK``."""

    lower: int  # the tick of the spec's lower end
    upper: int  # the tick of its upper end (below ``lower`` on a reversed servo)

    @property
    def limits(self) -> tuple[int, int]:
        """(min_tick, max_tick)."""
        return min(self.lower, self.upper), max(self.lower, self.upper)

    @property
    def outside(self) -> tuple[str, ...]:
        """The ends (``"lower"``, ``"upper"``) whose tick lies outside ``MIN_POSITION_TICK..MAX_POSITION_TICK``."""
        ends = (("lower", self.lower), ("upper", self.upper))
        return tuple(name for name, tick in ends if not MIN_POSITION_TICK <= tick <= MAX_POSITION_TICK)


def end_ticks(spec: ServoSpec, curve: Curve) -> EndTicks:
    """Where ``curve`` puts the ends of ``spec``'s range: the one computation :func:`check_servo` refuses a
    range by, shared with those that predict it (``servoface check`` before a calibration exists)."""
    lower, upper = (int(t) for t in round_ticks(curve.forward(np.array([spec.lower, spec.upper]))))
    return EndTicks(lower, upper)


def default_curve_kind(spec: ServoSpec) -> str:
    """Joints are geared straight to the servo (linear); anchors go through cables/linkages (pchip)."""
    return "linear" if spec.kind == "joint" else "pchip"


def far_outside(spec: ServoSpec, target: float) -> str | None:
    """Why a measured ``target`` cannot be meant (more than `FAR_OUTSIDE_RANGES` range widths past either
    end of the spec's range: a typo, or another unit), else None. Points a little past the ends are welcome
    (they pin the curve's ends); one far away would pull a fitted line flat across the whole range."""
    span = spec.upper - spec.lower
    reach = FAR_OUTSIDE_RANGES * span
    if spec.lower - reach <= target <= spec.upper + reach:
        return None
    return (
        f"servo '{spec.role}': measured target {target:g} {spec.unit} is far outside its range "
        f"{spec.lower:g}..{spec.upper:g} {spec.unit} (more than {FAR_OUTSIDE_RANGES:g} range width past it: "
        f"{spec.lower - reach:g}..{spec.upper + reach:g} accepted); a typo, or a target in another unit?"
    )


def check_coverage(spec: ServoSpec, points: NDArray[np.float64]) -> list[str]:
    """Raise CoverageError unless the points span [lower, upper] and none is `far_outside` it; return
    warnings about gaps."""
    for target in points[:, 0].tolist():
        if (why := far_outside(spec, target)) is not None:
            raise CoverageError(why)
    span = spec.upper - spec.lower
    tol = COVERAGE_TOLERANCE * span
    lo, hi = float(points[:, 0].min()), float(points[:, 0].max())
    if lo > spec.lower + tol or hi < spec.upper - tol:
        raise CoverageError(
            f"servo '{spec.role}': measured points span {lo:g}..{hi:g} {spec.unit} but the range is "
            f"{spec.lower:g}..{spec.upper:g} {spec.unit}; measure at (or past) both ends "
            f"(allowed shortfall {tol:g} {spec.unit})"
        )
    warnings = []
    inside = np.sort(np.concatenate([[spec.lower, spec.upper], points[:, 0]]))
    inside = inside[(inside >= spec.lower) & (inside <= spec.upper)]
    gaps = np.diff(inside)
    if gaps.size and gaps.max() > GAP_WARNING * span:
        i = int(np.argmax(gaps))
        warnings.append(
            f"servo '{spec.role}': no measured point between {inside[i]:g} and {inside[i + 1]:g} {spec.unit} "
            f"({gaps[i] / span:.0%} of the range); add a point there"
        )
    return warnings


def fit_servo(
    spec: ServoSpec,
    points: ArrayLike,
    curve_kind: str | None = None,
    *,
    neutral_tick: int | None = None,
) -> FitReport:
    """Fit a curve of ``curve_kind`` (default by spec kind) through ``points`` and check it.

    Limits: the spec's target range, with tick limits = the rounded ticks of its ends. Neutral tick:
    ``neutral_tick`` if given (a captured one), else the rounded tick of the spec's neutral target.
    """
    kind = curve_kind or default_curve_kind(spec)
    pts = as_points(points, what=f"servo '{spec.role}' measured points")
    try:
        curve = fit_curve(kind, pts)
    except CalibrationError as err:
        raise type(err)(f"servo '{spec.role}': {err}") from err
    return check_servo(spec, curve, pts, neutral_tick=neutral_tick)


def check_servo(spec: ServoSpec, curve: Curve, points: ArrayLike, *, neutral_tick: int | None = None) -> FitReport:
    """Checks and limits shared by every way of making a curve (see :func:`fit_servo`)."""
    kind = curve.kind
    pts = as_points(points, what=f"servo '{spec.role}' measured points")
    warnings = check_coverage(spec, pts)
    residual = float(np.max(np.abs(curve.forward(pts[:, 0]) - pts[:, 1])))
    if residual > RESIDUAL_WARNING_TICK:
        warnings.append(
            f"servo '{spec.role}': the {kind} curve misses a measured point by {residual:.1f} tick "
            f"(> {RESIDUAL_WARNING_TICK:g}); the servo may not be {kind} - try 'pchip', or re-measure"
        )
    ends = end_ticks(spec, curve)
    tick_lo, tick_hi = ends.limits
    if ends.outside:
        raise CalibrationError(
            f"servo '{spec.role}': its range {spec.lower:g}..{spec.upper:g} {spec.unit} maps to ticks "
            f"{tick_lo}..{tick_hi}, outside {MIN_POSITION_TICK}..{MAX_POSITION_TICK}; re-mount the horn"
        )
    if tick_hi == tick_lo:
        raise CalibrationError(
            f"servo '{spec.role}': its whole range {spec.lower:g}..{spec.upper:g} {spec.unit} maps to one tick "
            f"({tick_lo}): the measured ticks do not change with the target; re-measure"
        )
    if tick_hi - tick_lo < 8:
        warnings.append(
            f"servo '{spec.role}': the whole range is only {tick_hi - tick_lo} tick; resolution will be poor"
        )
    neutral = int(round_ticks(curve.forward(np.array(spec.neutral)))) if neutral_tick is None else neutral_tick
    neutral = min(max(neutral, tick_lo), tick_hi)
    servo = ServoCalibration(
        spec.role,
        spec.servo_id,
        spec.model,
        curve,
        tick_lo,
        tick_hi,
        neutral,
        spec.unit,
        min_target=spec.lower,
        max_target=spec.upper,
        measured_points=pts,
    )
    return FitReport(servo, residual, warnings)


def fit_coupling(
    servo: ServoCalibration,
    neighbours: Sequence[str],
    inputs: ArrayLike,
    outputs: ArrayLike,
    *,
    smoothing: float = 0.0,
) -> RbfCoupling:
    """Fit an RBF coupling (own tick, neighbour ticks...) -> target for ``servo`` and check it.

    The map must be strictly monotone along the own-tick axis over [min_tick, max_tick] for every
    neighbour value on a grid spanning the measured inputs; otherwise the servo tick for a pull would not
    be unique and NotMonotoneError is raised naming where.
    """
    rbf = RbfMap.fit(inputs, outputs, smoothing=smoothing)
    if rbf.dims != 1 + len(neighbours):
        raise CalibrationError(
            f"servo '{servo.role}': coupling inputs have {rbf.dims} columns; expected 1 + {len(neighbours)}"
        )
    data = rbf.inputs
    axes = [np.linspace(data[:, j].min(), data[:, j].max(), 7) for j in range(1, rbf.dims)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, rbf.dims - 1)
    points = np.hstack([np.zeros((grid.shape[0], 1)), grid])
    direction = rbf.axis_direction(points, 0, float(servo.min_tick), float(servo.max_tick))
    if np.any(direction == 0.0) or np.unique(direction).size > 1:
        i = int(np.argmax(direction != direction[0])) if np.all(direction != 0.0) else int(np.argmax(direction == 0))
        where = ", ".join(f"{n}={v:g}" for n, v in zip(neighbours, grid[i], strict=True))
        raise NotMonotoneError(
            f"servo '{servo.role}': the coupled map is not strictly monotone in its own tick over "
            f"{servo.min_tick}..{servo.max_tick} at {where}; expected one tick per pull"
        )
    return RbfCoupling(tuple(neighbours), rbf)


COUPLED_SLICE_SAMPLES = 13


def fit_coupled_servo(
    spec: ServoSpec,
    neighbours: Sequence[str],
    neighbour_neutral_tick: Sequence[int],
    inputs: ArrayLike,
    targets: ArrayLike,
    *,
    smoothing: float = 0.0,
) -> FitReport:
    """A skin anchor whose pull depends on its own tick and its neighbours' ticks.

    inputs: (k, 1 + d) ticks (own first, then ``neighbours`` in order); targets: (k,) measured pulls.
    The RBF map is fitted to all rows; the servo's 1-D curve (used when the neighbours are not known, and
    for its limits) is the map's slice with every neighbour at its neutral tick, stored as a PCHIP spline
    through 13 samples across the measured own ticks. Both must be strictly monotone in the own tick.
    """
    x = np.asarray(inputs, dtype=np.float64)
    y = np.asarray(targets, dtype=np.float64)
    rbf = RbfMap.fit(x, y, smoothing=smoothing)
    if rbf.dims != 1 + len(neighbours) or len(neighbour_neutral_tick) != len(neighbours):
        raise CalibrationError(
            f"servo '{spec.role}': coupling inputs have {rbf.dims} columns; expected 1 + {len(neighbours)}"
        )
    warnings = []
    for j, (name, tick) in enumerate(zip(neighbours, neighbour_neutral_tick, strict=True), start=1):
        lo, hi = x[:, j].min(), x[:, j].max()
        if not lo <= tick <= hi:
            warnings.append(
                f"servo '{spec.role}': neighbour '{name}' was measured at {lo:g}..{hi:g} tick, not around "
                f"its neutral {tick}; the slice at neutral is extrapolated"
            )
    own = np.linspace(x[:, 0].min(), x[:, 0].max(), COUPLED_SLICE_SAMPLES)
    at_neutral = np.column_stack([own, np.tile(np.asarray(neighbour_neutral_tick, dtype=np.float64), (len(own), 1))])
    pulls = rbf.evaluate(at_neutral)
    report = fit_servo(spec, np.column_stack([pulls, own]), "pchip")
    coupling = fit_coupling(report.servo, neighbours, x, y, smoothing=smoothing)
    neutral_rows = np.all(x[:, 1:] == np.asarray(neighbour_neutral_tick, dtype=np.float64), axis=1)
    measured = np.column_stack([y[neutral_rows], x[neutral_rows, 0]]) if neutral_rows.any() else np.zeros((0, 2))
    servo = dataclasses.replace(report.servo, coupling=coupling, measured_points=measured)
    residual = float(np.max(np.abs(rbf.evaluate(x) - y)))
    return FitReport(
        servo,
        report.max_residual_tick,
        report.warnings
        + warnings
        + (
            [f"servo '{spec.role}': the coupled map misses a measured pull by {residual:.3g} {spec.unit}"]
            if residual > 1e-6
            else []
        ),
    )
