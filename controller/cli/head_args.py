"""What the sub-commands that drive a head share: its arguments (head, port or emulator, baud, rate,
calibration, trace) and opening the `Face` from them."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Mapping

    from servoface.calibration import HeadCalibration
    from servoface.controller.face import Face
    from servoface.controller.safe_stop import StopReport
    from servoface.controller.script import Script
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
    add_read_arguments(parser)


FAST_READ_CHOICES = {"auto": "auto", "on": True, "off": False}  # --fast-sync-read -> Driver(fast_sync_read=)


SENTINEL_CHOICES = {"on": True, "off": False}  # --position-sentinel -> Driver(position_sentinel=)


def add_read_arguments(parser: argparse.ArgumentParser) -> None:
    """--fast-sync-read auto|on|off and --position-sentinel on|off: how the driver reads positions
    (`Driver`'s ``fast_sync_read`` and ``position_sentinel``)."""
    parser.add_argument(
        "--fast-sync-read",
        choices=tuple(FAST_READ_CHOICES),
        default="auto",
        help="read positions with Fast Sync Read: auto (default: probed at start-up, used if every servo "
        "answers), on (forced), off (plain Sync Read, e.g. firmware without it: no start-up probe)",
    )
    parser.add_argument(
        "--position-sentinel",
        choices=tuple(SENTINEL_CHOICES),
        default="on",
        help="read positions through four Indirect Address slots that also show a reset servo at once: on "
        "(default), off (nothing written to Indirect Address, e.g. slots another tool uses: positions read "
        "directly, a reset seen by the status read)",
    )


def read_options(args: argparse.Namespace) -> dict[str, Any]:
    """``fast_sync_read`` and ``position_sentinel`` for `Face.open` / `open_head`, as the arguments name them
    (the defaults where a command has no such arguments)."""
    return {
        "fast_sync_read": FAST_READ_CHOICES[getattr(args, "fast_sync_read", "auto")],
        "position_sentinel": SENTINEL_CHOICES[getattr(args, "position_sentinel", "on")],
    }


def open_errors() -> tuple[type[BaseException], ...]:
    """The errors opening a head can raise for bad input or a missing port (reported, exit 2)."""
    from servoface.calibration import CalibrationError
    from servoface.controller.errors import ControllerError
    from servoface.hardware.errors import HardwareError
    from servoface.sim.errors import SimError

    return (ControllerError, SimError, CalibrationError, HardwareError, ValueError, OSError)


def check_expression(head: Head, name: str) -> None:
    """Refuse an expression ``name`` the head's library does not have (ControllerError naming the ones it
    has), or one the head cannot show (`check_on_head`), before anything is opened: a typo must not switch
    torque on, nor an intensity the head's AU table refuses."""
    from servoface.controller.errors import ControllerError
    from servoface.sim.expressions import load_library

    known = load_library(head.expressions_path or head.face_type)
    _check_library_face(head, known)  # (a library of another face type: said as such, not "unknown name")
    if name not in known:
        from servoface.controller.face import unknown_expression

        raise ControllerError(unknown_expression(name, known, head))
    check_on_head(head, known, [name])


NEUTRAL = "neutral"  # the rest pose: a library need not list it


def check_on_head(head: Head, library: Mapping[str, Any], names: list[str], *, model: Any = None) -> None:
    """Solve each expression of ``names`` (names of ``library``) at its apex on the head's face model
    (``model``: one already built for the head, else built here), so that what the head's own AU table,
    direct table or muscles refuse (an AU it does not know, an intensity out of its range, a library of
    another face type) is bad input named before anything is opened or rendered: ExpressionError naming the
    expression and the library file, or the profile's HeadProfileError."""
    from servoface.controller.timeline_on_head import pose_refusal
    from servoface.sim.errors import ExpressionError
    from servoface.sim.face_model import FaceModel

    _check_library_face(head, library)
    where = _library_where(library)
    model = FaceModel(head) if model is None else model
    for name in names:
        if name == NEUTRAL and name not in library:
            continue  # the rest pose, which every head shows
        why = pose_refusal(model.solve, library[name].apex(), f"expression {name!r}{where}", head.name)
        if why is not None:
            raise ExpressionError(why)


def _library_where(library: Mapping[str, Any]) -> str:
    source = getattr(library, "source_path", None)
    return f" in {source}" if source is not None else ""


def _check_library_face(head: Head, library: Mapping[str, Any]) -> None:
    """ExpressionError if ``library`` holds expressions of another face type than the head's."""
    from servoface.sim.errors import ExpressionError

    other = sorted({e.face_type for e in library.values() if getattr(e, "face_type", head.face_type) != head.face_type})
    if other:
        raise ExpressionError(
            f"the expression library{_library_where(library)} is for a {'/'.join(other)} face; head {head.name!r} "
            f"is a {head.face_type} face: expected a {head.face_type} library (its profile's 'expressions' key)"
        )


def check_script_on_head(head: Head, script: Script) -> None:
    """Solve what ``script`` plays on the head's face model before anything is opened
    (`servoface.controller.timeline_on_head`): ScriptError naming the script file, the expression and its
    track, or the profile's HeadProfileError."""
    from servoface.controller.timeline_on_head import check_timeline_on_head
    from servoface.sim.face_model import FaceModel

    check_timeline_on_head(script.timeline, FaceModel(head).solve, str(script.source), head.name)


MAX_ROLES_NAMED = 4  # a calibration of another head lacks most roles: name a few, count the rest


def checked_calibration(args: argparse.Namespace, head: Head) -> HeadCalibration:
    """The calibration ``--calibration`` names (else the one the profile names), read and checked against
    the head's servos (`head_servos.calibration_mismatches`): every role there, with the profile's servo ids
    and models, and a model the driver knows. Called before anything is opened or announced, so a missing or
    malformed file, one of another head, or one measured on other servo models, is refused with its own
    message and nothing else said (CalibrationError, ControllerError or HeadProfileError: exit 2);
    `open_face` then drives with the calibration returned. A command without --calibration (`node`) checks
    the profile's own."""
    from servoface.calibration.errors import CalibrationFileError
    from servoface.controller.head_servos import calibration_mismatches, servo_specs
    from servoface.controller.service import head_calibration

    given = getattr(args, "calibration", None)
    cal = head_calibration(head, given)  # a file that is missing or malformed names itself
    file = str(given if given is not None else head.calibration_path)
    check = f"servoface check {args.head}" + (f" --calibration {file}" if given is not None else "")
    fix = f"expected this head's calibration (`{check}` lists every difference)"
    found = calibration_mismatches(head, cal)
    missing = [m.role for m in found if m.kind == "missing"]
    if missing:
        named = ", ".join(missing[:MAX_ROLES_NAMED])
        if len(missing) > MAX_ROLES_NAMED:
            named += f" and {len(missing) - MAX_ROLES_NAMED} more"
        whose = f" (it is a calibration of head {cal.head!r})" if cal.head != head.name else ""
        raise CalibrationFileError(file, "servos", f"no servo for role(s) {named} of head {head.name!r}{whose}: {fix}")
    for kind, what in (("id", "servo ids"), ("model", "servo models")):
        moved = [f"{m.role} {m.profile} -> {m.calibration}" for m in found if m.kind == kind]
        if moved:
            named = ", ".join(moved[:MAX_ROLES_NAMED]) + (" ..." if len(moved) > MAX_ROLES_NAMED else "")
            raise CalibrationFileError(
                file,
                "servos",
                f"{what} differ from the profile of head {head.name!r} (role: profile -> file: {named}): {fix}",
            )
    servo_specs(head, cal)  # a model the driver knows, as opening the head checks it
    return cal


def open_face(args: argparse.Namespace, head: Head, calibration: HeadCalibration | None = None) -> Face:
    """The head on the port or the emulator the arguments name, driven with ``calibration`` (from
    `checked_calibration`; None: read ``--calibration`` or the profile's here). A chain that does not answer
    raises BusTimeoutError with a hint at the baud rate (the likeliest cause on a fresh set-up)."""
    from servoface.controller.face import Face
    from servoface.hardware.errors import BusTimeoutError

    try:
        return Face.open(
            head,
            port=args.port,
            emulate=args.emulate,
            baud=args.baud,
            rate_hz=args.rate,
            calibration=calibration if calibration is not None else args.calibration,
            **read_options(args),
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


EXIT_OK = 0
EXIT_FAILURE = 1  # the bus failed, or servos ended latched / missing
EXIT_USAGE = 2  # bad arguments or input: nothing was driven
EXIT_UNSAFE = 3  # torque-off not confirmed on some servo: it may still be powered


class TraceFile:
    """``--trace FILE``: every frame's trace streamed as a JSON line into a temp file beside FILE as the run
    goes (nothing kept in memory), renamed onto FILE when the run ends — however it ends."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self._fh: Any = None
        self._tmp: Path | None = None
        self.writer: Any = None

    def open(self) -> TraceFile:
        if self.path is None:
            return self
        import os
        import tempfile

        from servoface.controller.cli.outputs import writable_file
        from servoface.controller.trace_ring import TraceWriter

        self.path.parent.mkdir(parents=True, exist_ok=True)
        writable_file(self.path)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent)
        self._tmp = Path(tmp)
        self._fh = os.fdopen(fd, "w", encoding="utf-8")
        self.writer = TraceWriter(self._fh)
        return self

    def sink(self, trace: Any) -> None:
        if self.writer is not None:
            self.writer(trace)

    def discard(self) -> None:
        """Close and remove the temp file (the run never started): FILE is left as it was."""
        fh, self._fh = self._fh, None
        if fh is not None:
            fh.close()
        if self._tmp is not None and self._tmp.exists():
            self._tmp.unlink()

    def finish(self) -> str | None:
        """Close and rename into place; the line to print (None without --trace)."""
        if self._fh is None or self._tmp is None or self.path is None:
            return None
        import os

        fh, self._fh = self._fh, None
        try:
            fh.flush()
            os.fsync(fh.fileno())
            fh.close()
            os.replace(self._tmp, self.path)
        except BaseException:
            if self._tmp.exists():
                self._tmp.unlink()
            raise
        return f"trace written to {self.path} ({self.writer.count} frames)"


def exit_status(report: StopReport | None, *, failed: bool, signal_code: int | None) -> int:
    """3 if any servo was not reached, 1 after a bus failure or with servos latched/missing, else 128+signal
    for a run a signal stopped (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), else 0."""
    if report is not None and not report.safe:
        return EXIT_UNSAFE
    if failed or (report is not None and (report.latched or report.missing)):
        return EXIT_FAILURE
    if signal_code is not None:
        return signal_code
    return EXIT_OK


def print_stop(command: str, report: StopReport | None) -> None:
    """The stop path's closing lines (stdout), and a warning on stderr when a servo was not reached."""
    import sys

    if report is None:
        return
    for line in report.lines():
        print(line)
    if not report.safe:
        print(
            f"servoface {command}: torque-off NOT confirmed on servo(s) {list(report.unreached)}: "
            "they may still be powered; switch the servo supply off",
            file=sys.stderr,
        )
