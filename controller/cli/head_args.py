"""What the sub-commands that drive a head share: its arguments (head, port or emulator, baud, rate,
calibration, trace) and opening the `Face` from them."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from servoface.controller.face import Face
    from servoface.sim.head import Head


def add_head_arguments(parser: argparse.ArgumentParser) -> None:
    """--head, --port | --emulate, --baud, --rate, --calibration, --trace."""
    parser.add_argument("--head", default="human", help="built-in head (human, dog) or a profile folder")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--port", help="serial port of the chain, e.g. /dev/ttyUSB0 (or a pty from `servoface emulate`)")
    where.add_argument("--emulate", action="store_true", help="run on an in-process emulated chain")
    parser.add_argument("--baud", type=int, default=1_000_000, help="bus speed in bps (default 1000000)")
    parser.add_argument("--rate", type=float, default=50.0, help="control rate in Hz (default 50)")
    parser.add_argument("--calibration", type=Path, help="calibration JSON (default: the one the profile names)")
    parser.add_argument("--trace", type=Path, help="write every frame's trace as JSON lines to this file")


def rate_problem(args: argparse.Namespace) -> str | None:
    """A message if --rate is out of range, else None."""
    if not (0 < args.rate <= 1000):
        return f"--rate must be within 0..1000 Hz, got {args.rate}"
    return None


def open_errors() -> tuple[type[BaseException], ...]:
    """The errors opening a head can raise for bad input or a missing port (reported, exit 2)."""
    from servoface.calibration import CalibrationError
    from servoface.controller.errors import ControllerError
    from servoface.hardware.errors import HardwareError
    from servoface.sim.errors import SimError

    return (ControllerError, SimError, CalibrationError, HardwareError, ValueError, OSError)


def open_face(args: argparse.Namespace, head: Head) -> Face:
    """The head on the port or the emulator the arguments name. A chain that does not answer raises
    BusTimeoutError with a hint at the baud rate (the likeliest cause on a fresh set-up)."""
    from servoface.controller.face import Face
    from servoface.hardware.errors import BusTimeoutError

    try:
        return Face.open(
            head,
            port=args.port,
            emulate=args.emulate,
            baud=args.baud,
            rate_hz=args.rate,
            calibration=args.calibration,
        )
    except BusTimeoutError as err:
        if args.port is None:
            raise
        raise BusTimeoutError(
            f"{err}. No reply at {args.baud} bps: check power and wiring, and the servos' baud rate "
            f"(new servos ship at 57600): `servoface scan --port {args.port} --baud all` finds it; "
            "then pass --baud",
            err.servo_ids,
        ) from err
