"""Errors of the calibration package."""


class CalibrationError(Exception):
    """Base of every calibration error; messages name the file, servo and field."""


class CalibrationFileError(CalibrationError):
    """A calibration file is missing, malformed, or of an unknown schema version."""


class CurveError(CalibrationError):
    """A curve cannot be built or evaluated (not monotone, not invertible, out of its domain)."""
