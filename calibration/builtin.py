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
from servoface.calibration.curves import CENTRE_TICK, TICKS_PER_DEG, Curve, LinearCurve, PchipCurve
from servoface.calibration.errors import CalibrationError
from servoface.calibration.fileformat import save_calibration
from servoface.calibration.fitting import EndTicks, FitReport, check_servo, end_ticks
from servoface.calibration.head import CalibrationMetadata, HeadCalibration
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
        targets = np.unique([spec.lower, spec.neutral, spec.upper])
        return curve, np.stack([targets, curve.forward(targets)], axis=1)
    points = crank_points(spec)
    return PchipCurve(points), points


def builtin_servo(spec: ServoSpec) -> FitReport:
    """The calibration of one emulated servo (see the module docstring)."""
    curve, points = builtin_curve(spec)
    return check_servo(spec, curve, points, neutral_tick=CENTRE_TICK)


@dataclass(frozen=True)
class BuiltinRefusal:
    """Why the emulated servo cannot take a spec: ``calibrate --builtin`` and ``--template`` refuse it."""

    error: CalibrationError  # what they say
    ends: EndTicks | None  # where its curve puts the range's ends (None: no curve could be made)


def builtin_refusal(spec: ServoSpec) -> BuiltinRefusal | None:
    """:func:`builtin_servo`'s refusal of ``spec``, or None when it takes it: the same steps, so a caller
    that predicts the refusal (``servoface check`` before a calibration exists) cannot disagree with it."""
    try:
        curve, points = builtin_curve(spec)
    except CalibrationError as err:
        return BuiltinRefusal(err, None)
    try:
        check_servo(spec, curve, points, neutral_tick=CENTRE_TICK)
    except CalibrationError as err:
        return BuiltinRefusal(err, end_ticks(spec, curve))
    return None


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
