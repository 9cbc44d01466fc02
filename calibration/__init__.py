"""Servo calibration: curves from actuator targets (deg or mm) to goal ticks and back, files, procedure.

Leaf package: imports nothing else of servoface. The procedure is handed a bus by its caller.

Main entry points::

    from servoface.calibration import load_calibration, HeadCalibration
    cal = load_calibration("sim/heads/human/calibration.json")
    goals = cal.targets_to_goals({"jaw": 12.0, "brow_inner_l": 3.0})   # {18: 2185, 1: ...}
    targets = cal.goals_to_targets(goals)                                # {"jaw": 11.98..., ...}
"""

from servoface.calibration.curves import (
    CENTRE_TICK,
    TICKS_PER_DEG,
    TICKS_PER_TURN,
    Curve,
    LinearCurve,
    PchipCurve,
    PiecewiseLinearCurve,
    fit_curve,
)
from servoface.calibration.errors import (
    CalibrationError,
    CalibrationFileError,
    CoverageError,
    CurveError,
    MeasurementCsvError,
    NotMonotoneError,
    OutOfRangeError,
    ProcedureAborted,
    ProcedureError,
    TargetOutOfRangeError,
    TickOutOfRangeError,
    UnknownServoError,
)
from servoface.calibration.fileformat import (
    SCHEMA_VERSION,
    calibration_from_dict,
    calibration_to_dict,
    load_calibration,
    save_calibration,
)
from servoface.calibration.head import CalibrationMetadata, HeadCalibration
from servoface.calibration.rbf import RbfMap
from servoface.calibration.servo import RbfCoupling, ServoCalibration
from servoface.calibration.spec import ServoSpec

__all__ = [
    "CENTRE_TICK",
    "SCHEMA_VERSION",
    "TICKS_PER_DEG",
    "TICKS_PER_TURN",
    "CalibrationError",
    "CalibrationFileError",
    "CalibrationMetadata",
    "CoverageError",
    "Curve",
    "CurveError",
    "HeadCalibration",
    "LinearCurve",
    "MeasurementCsvError",
    "NotMonotoneError",
    "OutOfRangeError",
    "PchipCurve",
    "PiecewiseLinearCurve",
    "ProcedureAborted",
    "ProcedureError",
    "RbfCoupling",
    "RbfMap",
    "ServoCalibration",
    "ServoSpec",
    "TargetOutOfRangeError",
    "TickOutOfRangeError",
    "UnknownServoError",
    "calibration_from_dict",
    "calibration_to_dict",
    "fit_curve",
    "load_calibration",
    "save_calibration",
]
