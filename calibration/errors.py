"""Errors of the calibration package.

Every message names what it is about (file and JSON path, CSV line, servo role) and what was expected.
"""

from __future__ import annotations


class CalibrationError(Exception):
    """Base of every calibration error; messages name the file, servo and field."""


class CalibrationFileError(CalibrationError):
    """A calibration file is missing, malformed, or of an unknown schema version.

    ``file`` is the path (or ``"<dict>"`` for in-memory data), ``json_path`` the place in it such as
    ``servos[3].curve.points`` (empty for the whole file).
    """

    def __init__(self, file: str, json_path: str, message: str) -> None:
        self.file = file
        self.json_path = json_path
        where = f"{file}: {json_path}" if json_path else file
        super().__init__(f"{where}: {message}")


class MeasurementCsvError(CalibrationFileError):
    """A measurement CSV (``role,target,tick`` rows) is malformed; ``line`` is 1-based (0 = whole file)."""

    def __init__(self, file: str, line: int, message: str) -> None:
        self.line = line
        super().__init__(file, f"line {line}" if line else "", message)


class CurveError(CalibrationError):
    """A curve cannot be built or evaluated (not monotone, not invertible, out of its domain)."""


class NotMonotoneError(CurveError):
    """Measured points or a fitted map are not strictly monotone where they must be."""


class CoverageError(CalibrationError):
    """Measured points do not span the range the servo must cover."""


class OutOfRangeError(CalibrationError, ValueError):
    """A target or tick is non-finite or outside a servo's calibrated limits.

    ``role`` names the servo, ``value`` is the offending value, ``lower``/``upper`` the accepted range.
    """

    def __init__(self, role: str, value: float, lower: float, upper: float, unit: str, what: str) -> None:
        self.role = role
        self.value = value
        self.lower = lower
        self.upper = upper
        self.unit = unit
        super().__init__(
            f"servo '{role}': {what} {value!r} {unit} is outside its calibrated range [{lower:g}, {upper:g}] {unit}"
            if value == value and abs(value) != float("inf")
            else f"servo '{role}': {what} {value!r} is not a finite number (expected {lower:g}..{upper:g} {unit})"
        )


class TargetOutOfRangeError(OutOfRangeError):
    """An actuator target (deg or mm) is non-finite or outside the servo's calibrated target limits."""

    def __init__(self, role: str, value: float, lower: float, upper: float, unit: str) -> None:
        super().__init__(role, value, lower, upper, unit, "target")


class TickOutOfRangeError(OutOfRangeError):
    """A position tick is non-finite or outside the servo's calibrated tick limits."""

    def __init__(self, role: str, value: float, lower: float, upper: float) -> None:
        super().__init__(role, value, lower, upper, "tick", "position")


class UnknownServoError(CalibrationError, KeyError):
    """A role or servo id is not part of the head's calibration."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class ProcedureError(CalibrationError):
    """The calibration procedure cannot continue (aborted by the user, bad capture, bus refused)."""


class ProcedureAborted(ProcedureError):
    """The operator aborted the calibration procedure; nothing was saved."""
