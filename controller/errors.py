"""Errors of the controller package."""


class ControllerError(Exception):
    """Base of every error raised by servoface's controller package."""


class FrameError(ControllerError):
    """An AU frame is invalid: non-finite or out-of-range intensity, unknown AU name, bad time."""


class ScriptError(ControllerError):
    """A timeline script is malformed; the message names the file, key path and what was expected."""


class TimelineError(ControllerError):
    """A timeline, clip, movement share, envelope or event list is malformed (built from code)."""


class LoopError(ControllerError):
    """The fixed-rate loop was misconfigured (rate, clock) or run twice at once."""
