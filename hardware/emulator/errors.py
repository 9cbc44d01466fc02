"""Errors of the servo-chain emulator (apart from ``servoface.hardware.errors``: the emulator stays independent)."""


class EmulatorError(Exception):
    """Base of every error raised by the emulator."""


class EmulatorConfigError(EmulatorError, ValueError):
    """A chain, servo, model or fault description is invalid (names the field and what was expected)."""


class PacketError(EmulatorError, ValueError):
    """Bytes do not form a valid Protocol 2.0 packet (names what was wrong)."""


class RegisterError(EmulatorError, KeyError):
    """A register name or address is unknown for a model, or a value does not fit the register."""


class PortClosedError(EmulatorError, OSError):
    """The in-process serial endpoint or pty was used after it was closed."""
