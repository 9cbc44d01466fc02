"""Errors of the hardware package. Messages name the servo id, register or port and what was expected."""


class HardwareError(Exception):
    """Base of every error raised by servoface's hardware package."""


class BusError(HardwareError):
    """Communication on the bus failed (port, packet, reply)."""


class BusTimeoutError(BusError):
    """A servo that should have answered did not answer in time."""


class BusCorruptError(BusError):
    """A reply arrived but was malformed or failed its CRC."""


class ServoFault(HardwareError):
    """A servo reported a hardware error (overload, overheating, voltage, encoder, electrical shock)."""


class HardwareConfigError(HardwareError):
    """A servo description or register value is invalid (names the field and what was expected)."""
