"""Generator of the built-in heads' calibration files, matching their emulated servos.

The emulated servos are ideal X-series servos: 4096 ticks per turn, 2048 at the actuator's neutral.

- Joint actuators are geared 1:1 to the horn: linear, 4096/360 tick per degree, direction per servo
  (mirrored mounting: ``_r`` servos reversed unless the spec says otherwise).
- Skin anchors are pulled by a cable on a crank (a linkage): pull_mm - neutral_mm = r * sin(angle), with
  r chosen so the larger end of the range sits at a 60 deg crank angle. That is non-linear, so it is
  stored as a monotone spline (PCHIP) through 13 points plus neutral, and exercises the point-curve path.

It takes the servo list as data (:class:`ServoSpec`), never imports sim: the controller CLI
(``servoface calibrate --head human --builtin --out ...``) builds the specs from the head profile and
calls :func:`write_builtin`, so the files can be regenerated whenever the head's ranges change.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from servoface.calibration.curves import CENTRE_TICK, TICKS_PER_DEG, TICKS_PER_TURN, Curve, LinearCurve, PchipCurve
from servoface.calibration.errors import CalibrationError
from servoface.calibration.fileformat import save_calibration
from servoface.calibration.fitting import EndTicks, FitReport, check_servo, end_ticks
from servoface.calibration.head import CalibrationMetadata, HeadCalibration
from servoface.calibration.servo import MAX_POSITION_TICK, MIN_POSITION_TICK
from servoface.calibration.spec import ServoSpec

CRANK_MAX_ANGLE_DEG = 60.0
ANCHOR_POINTS = 13  # PCHIP through 13 crank points stays within 0.3 tick of the crank


def crank_radius_mm(spec: ServoSpec) -> float:
    """Crank radius that reaches the larger end of the pull range at CRANK_MAX_ANGLE_DEG."""
    reach = max(abs(spec.upper - spec.neutral), abs(spec.lower - spec.neutral))
    return reach / math.sin(math.radians(CRANK_MAX_ANGLE_DEG))


def crank_points(spec: ServoSpec, n: int = ANCHOR_POINTS) -> np.ndarray:
    """(n + 1, 2) float: (pull_mm, tick) on the crank, from lower to upper, including neutral."""
    r = crank_radius_mm(spec)
    a_lo = math.degrees(math.asin((spec.lower - spec.neutral) / r))
    a_hi = math.degrees(math.asin((spec.upper - spec.neutral) / r))
    angles = np.unique(np.concatenate([np.linspace(a_lo, a_hi, n), [0.0]]))
    pulls = spec.neutral + r * np.sin(np.radians(angles))
    ticks = CENTRE_TICK + spec.direction * angles * TICKS_PER_DEG
    pts = np.stack([pulls, ticks], axis=1)
    # the neutral pull must land exactly on the centre tick
    pts[angles == 0.0] = (spec.neutral, float(CENTRE_TICK))
    return pts


def builtin_curve(spec: ServoSpec) -> tuple[Curve, NDArray[np.float64]]:
    """The emulated servo's curve for ``spec`` and the (k, 2) float (target, tick) points it is checked on."""
    if spec.kind == "joint":
        gain = spec.direction * TICKS_PER_DEG
        curve = LinearCurve(CENTRE_TICK - gain * spec.neutral, TICKS_PER_DEG, spec.direction)
        lower, neutral, upper = curve.forward(np.array([spec.lower, spec.neutral, spec.upper])).tolist()
        # a neutral within float rounding of an end (an end at 1e-136 deg) would be a second point on its tick
        between = [spec.neutral] if neutral not in (lower, upper) else []
        targets = np.array([spec.lower, *between, spec.upper])
        return curve, np.stack([targets, curve.forward(targets)], axis=1)
    points = crank_points(spec)
    return PchipCurve(points), points


MIN_SPAN_DEG = 1.0 / TICKS_PER_DEG  # one tick: 0.088 deg
MAX_SPAN_DEG = (MAX_POSITION_TICK - MIN_POSITION_TICK) / TICKS_PER_DEG  # 4095 ticks: 359.9 deg


def expected_span() -> str:
    """What a joint actuator's range may span at most on an ideal servo, in words."""
    return (
        f"a span of at most {MAX_SPAN_DEG:.1f} deg ({MAX_POSITION_TICK - MIN_POSITION_TICK} ticks of a servo "
        f"turning with the joint, {TICKS_PER_TURN} ticks a turn)"
    )


def expected_ticks_apart() -> str:
    """What a joint actuator's range must reach at least on an ideal servo, in words: its ends on two
    ticks (goals round to the nearest tick, so a span under one tick may or may not)."""
    return (
        f"its ends on two different ticks of a servo turning with the joint ({TICKS_PER_TURN} ticks a turn; "
        f"any span of {MIN_SPAN_DEG:.3f} deg or more is)"
    )


def expected_reach() -> str:
    """What a joint actuator's range must reach on an ideal servo, in words."""
    return (
        f"both ends within {MIN_POSITION_TICK}..{MAX_POSITION_TICK} of a servo turning with the joint, its "
        f"neutral at tick {CENTRE_TICK} ({TICKS_PER_TURN} ticks a turn)"
    )


def _past(name: str, spec: ServoSpec, tick: int) -> str:
    """One end of a joint range that lands outside the goals: where, and the room on its side."""
    target = spec.upper if name == "upper" else spec.lower
    room = MAX_POSITION_TICK - CENTRE_TICK if tick > MAX_POSITION_TICK else CENTRE_TICK - MIN_POSITION_TICK
    limit = MAX_POSITION_TICK if tick > MAX_POSITION_TICK else MIN_POSITION_TICK
    return (
        f"the {name} end, {abs(target - spec.neutral):g} deg from neutral, lands on tick {tick}, past {limit}: "
        f"that side has {room} ticks ({room / TICKS_PER_DEG:.1f} deg)"
    )


def reach_problem(spec: ServoSpec, ends: EndTicks) -> str | None:
    """Why the ideal servo cannot take the joint range of ``spec`` whose ends land on ``ends``, in words that
    start with what is expected (the caller puts the key that sets the range in front), or None when it can.

    The one wording of these refusals: :func:`builtin_servo` raises it, ``servoface check`` and
    ``calibrate --template`` print it after the profile key (``servoface.controller.joint_spans``).
    Anchors (a crank reaching its range at 60 deg) always fit: None.
    """
    if spec.kind != "joint":
        return None
    got = f"for servo {spec.role!r}, got [{spec.lower:g}, {spec.upper:g}]"
    span = spec.upper - spec.lower
    if ends.outside and span > MAX_SPAN_DEG:
        return f"expected {expected_span()} {got} (spans {span:g} deg, more than one servo turn; a typo?)"
    if ends.lower == ends.upper:
        return (
            f"expected {expected_ticks_apart()} {got} (spans {span:g} deg, less than one servo tick "
            f"({span * TICKS_PER_DEG:.2f} tick): both ends land on tick {ends.lower}; a typo? widen the range "
            f"to at least {MIN_SPAN_DEG:.3f} deg, or gear the joint so its servo turns further than it and "
            "calibrate from measured ticks)"
        )
    if ends.outside:
        past = "; ".join(_past(name, spec, getattr(ends, name)) for name in ends.outside)
        return (
            f"expected {expected_reach()} {got} with neutral {spec.neutral:g} deg ({past}; re-mount the horn so "
            "neutral sits nearer the middle of the travel and calibrate from measured ticks, or move the "
            "actuator's neutral_deg or narrow the range)"
        )
    return None


@dataclass(frozen=True)
class BuiltinRefusal:
    """Why the emulated servo cannot take a spec: ``calibrate --builtin`` and ``--template`` refuse it."""

    error: CalibrationError  # what they say
    reason: str | None = None  # a joint range it cannot reach: :func:`reach_problem`'s words (None: another)


def _builtin(spec: ServoSpec) -> FitReport | BuiltinRefusal:
    """The emulated servo's calibration of ``spec``, or why it cannot take it."""
    try:
        curve, points = builtin_curve(spec)
    except CalibrationError as err:
        return BuiltinRefusal(err)
    ends = end_ticks(spec, curve)
    if (why := reach_problem(spec, ends)) is not None:
        return BuiltinRefusal(CalibrationError(why), why)
    try:
        return check_servo(spec, curve, points, neutral_tick=CENTRE_TICK)
    except CalibrationError as err:
        return BuiltinRefusal(err)


def builtin_servo(spec: ServoSpec) -> FitReport:
    """The calibration of one emulated servo (see the module docstring); CalibrationError, in
    :func:`builtin_refusal`'s words, when the ideal servo cannot take its range."""
    got = _builtin(spec)
    if isinstance(got, BuiltinRefusal):
        raise got.error
    return got


def builtin_refusal(spec: ServoSpec) -> BuiltinRefusal | None:
    """:func:`builtin_servo`'s refusal of ``spec``, or None when it takes it: the same steps, so a caller
    that predicts the refusal (``servoface check`` before a calibration exists) cannot disagree with it."""
    got = _builtin(spec)
    return got if isinstance(got, BuiltinRefusal) else None


def builtin_calibration(head: str, specs: Sequence[ServoSpec], source: str = "") -> HeadCalibration:
    """A head calibration for the emulated servos of ``specs`` (in the given order)."""
    servos = [builtin_servo(s).servo for s in specs]
    meta = CalibrationMetadata(
        created_utc="",  # deterministic: regenerating an unchanged head gives a byte-identical file
        method="builtin",
        source=source or "servoface.calibration.builtin (ideal emulated servos)",
        notes="joints linear 4096/360 tick/deg, 2048 = neutral; anchors on a crank: "
        f"pull = r*sin(angle), r so the range ends at {CRANK_MAX_ANGLE_DEG:g} deg, stored as pchip",
    )
    return HeadCalibration(head, servos, meta)


def write_builtin(head: str, specs: Sequence[ServoSpec], path: str | os.PathLike[str], source: str = "") -> Path:
    """Generate and save (atomically) the built-in calibration of ``head``."""
    return save_calibration(builtin_calibration(head, specs, source), path)
