"""Errors of the hardware package. Messages name the servo id, register or port and what was expected."""

from collections.abc import Iterable


class HardwareError(Exception):
    """Base of every error raised by servoface's hardware package."""


class BusError(HardwareError):
    """Communication on the bus failed (port, packet, reply); ``servo_ids``: the ids addressed."""

    def __init__(self, what: str = "", servo_ids: Iterable[int] = ()) -> None:
        self.servo_ids = tuple(servo_ids)
        super().__init__(what)


class BusTimeoutError(BusError):
    """A servo that should have answered did not answer in time."""


class BusCorruptError(BusError):
    """A reply arrived but was malformed or failed its CRC."""


class ServoFault(HardwareError):
    """A servo reported a hardware error (overload, overheating, voltage, encoder, electrical shock)."""


class HardwareConfigError(HardwareError):
    """A servo description or register value is invalid (names the field and what was expected)."""


class BusClosedError(BusError):
    """The bus was used before `open()` or after `close()`."""


class BusDisconnectedError(BusError):
    """The port itself failed (USB adapter unplugged, pty closed): nothing can be sent until it reopens."""


class ServoStatusError(BusError):
    """A servo answered with a non-zero error number in its status packet (names the servo and the error)."""

    def __init__(self, servo_id: int, error_byte: int, what: str) -> None:
        self.servo_id = servo_id
        self.error_byte = error_byte
        self.error_number = error_byte & 0x7F
        self.alert = bool(error_byte & 0x80)
        super().__init__(what, (servo_id,))


class ServoDescriptionError(HardwareConfigError):
    """A servo description is invalid: names the servo id (and role) and the field."""

    def __init__(self, servo_id: int | None, field: str, what: str) -> None:
        self.servo_id = servo_id
        self.field = field
        super().__init__(what)


class ServoConfigMismatch(HardwareConfigError):
    """A register read back after configuration differs from what was written."""

    def __init__(self, servo_id: int, field: str, expected: int, actual: int) -> None:
        self.servo_id = servo_id
        self.field = field
        self.expected = expected
        self.actual = actual
        super().__init__(f"servo {servo_id}: {field} reads back {actual}, expected {expected} after writing it")


class ServoModelMismatch(ServoConfigMismatch):
    """The servo that answered on an id is a different model from the one the profile names for it."""

    def __init__(self, servo_id: int, expected: int, actual: int, expected_name: str, actual_name: str) -> None:
        super().__init__(servo_id, "model_number", expected, actual)
        self.args = (
            f"servo {servo_id}: wrong servo model on this id: it answers as {actual_name} (model number "
            f"{actual}) but the profile expects {expected_name} ({expected}); fit a {expected_name} at id "
            f"{servo_id} or correct the profile's model for it (`servoface scan` lists what answers)",
        )


class GoalRejectedError(HardwareConfigError):
    """A goal was refused before anything was sent (unknown id, non-integer, non-finite or outside limits)."""

    def __init__(self, servo_id: object, goal: object, what: str) -> None:
        self.servo_id = servo_id
        self.goal = goal
        super().__init__(what)


class DriverThreadError(HardwareError):
    """The driver was used from a thread that does not own the bus."""


class PortLockedError(BusError):
    """Another process holds the port (names its pid): two controllers must never drive one chain."""

    def __init__(self, port: str, holder_pid: int | None, lock_file: object) -> None:
        self.port = port
        self.holder_pid = holder_pid
        who = f"process {holder_pid}" if holder_pid is not None else "another process"
        super().__init__(
            f"port {port} is in use by {who} (lock {lock_file}); stop that controller first "
            "— two controllers on one chain would fight over its servos"
        )
