"""Errors of the sim package."""


class SimError(Exception):
    """Base of every error raised by servoface's sim package."""


class HeadProfileError(SimError):
    """A head profile (TOML, meshes) is invalid; the message carries the file and key path."""


class UnknownActionUnitError(SimError):
    """An AU name is not in the head's AU table."""


class ExpressionError(SimError):
    """An expression file or name is invalid or unknown."""


class RenderError(SimError):
    """Headless rendering is unavailable or failed (EGL missing, context creation failed)."""


class HeadMeshError(HeadProfileError):
    """A mesh named by a head profile is missing, unreadable or not a usable triangle mesh."""


class PoseError(SimError):
    """A head pose is invalid: unknown joint, non-finite angle, skin offsets of the wrong shape."""


class ActionUnitValueError(SimError):
    """An AU intensity is not a finite number in the AU's range (human 0..1, DFACS -1..1 unless stated)."""
