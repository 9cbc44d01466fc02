"""`servoface play EXPR|SCRIPT --head NAME|PATH (--port PORT [--baud B] | --emulate)`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from servoface.controller.cli.head_args import (
    TraceFile,
    add_head_arguments,
    check_expression,
    check_script_on_head,
    checked_calibration,
    exit_status,
    open_errors,
    open_face,
    print_stop,
)
from servoface.controller.cli.input_args import add_input_arguments, read_options
from servoface.controller.cli.terminal import printable
from servoface.controller.stop_signals import StopSignals

HELP = "play an expression or a timeline script on a head, on a real port or on the emulator"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "what",
        nargs="?",
        help="an expression name, a shipped script name (e.g. human_performance) or a script .toml "
        "(see `servoface list`)",
    )
    parser.add_argument(
        "--input",
        type=Path,
        help="instead of WHAT: a recorded tracker file (OpenFace/py-feat CSV, "
        "ARKit/MediaPipe blendshape CSV or JSON lines, MPEG-4 .fap) or a shipped sample "
        "(sample:openface_smile, see `servoface list samples`); see README 'Inputs'",
    )
    add_input_arguments(parser)
    add_head_arguments(parser)
    parser.add_argument(
        "--hold",
        type=float,
        default=None,
        help="seconds to hold an expression's apex, or the last frame of --input (default 1.5; 0 after a "
        "recording of several rows, 1.5 for a one-row still)",
    )
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        help="play a script or a recording for at most this many seconds (default: to its end)",
    )


def run(args: argparse.Namespace) -> int:
    # --rate, --hold, --duration and the input options were range-checked by options.parse_command
    if (args.what is None) == (args.input is None):
        print(
            "servoface play: give what to play (an expression or a script .toml) or --input FILE, one of them",
            file=sys.stderr,
        )
        return 2
    with StopSignals() as signals:  # SIGINT (twice: hurry to neutral), SIGTERM, SIGHUP: the stop path
        return _play(args, signals)


def _play(args: argparse.Namespace, signals: StopSignals) -> int:
    """Load and check, open (interruptible until torque-on), play on the head service, then the one stop path;
    exit 0, 1 (bus failure, servos latched/missing), 2 (bad input), 3 (torque-off not confirmed), 128+signal."""
    from servoface.controller.errors import ControllerError
    from servoface.controller.script import load_script
    from servoface.controller.service import ServiceClosedError
    from servoface.controller.shipped import is_shipped_script
    from servoface.controller.speech.script_play import play_script_speaking, prepare, speaks
    from servoface.controller.stop_signals import StopRequested, interruptible
    from servoface.hardware.errors import HardwareError
    from servoface.sim.errors import HeadProfileError, SimError
    from servoface.sim.heads import load_head

    recording = None
    prepared = None
    is_script = args.what is not None and (
        args.what.endswith(".toml") or Path(args.what).is_file() or is_shipped_script(args.what)
    )
    trace_file = TraceFile(args.trace)
    try:  # check what to play before opening the port: a typo must not switch torque on
        with interruptible():
            try:
                head = load_head(args.head)
            except HeadProfileError as err:  # as demo and preview: the head named once, and what to do
                from servoface.controller.cli.exits import head_hint, head_message

                print(f"servoface play: {printable(head_message(args.head, err))}", file=sys.stderr)
                print(f"  {head_hint(args.head)}", file=sys.stderr)
                return 2
            script = None
            if args.input is not None:
                from servoface.controller.inputs import HeadRanges, fit_recording, load_recording

                recording = load_recording(args.input, head.face_type, options=read_options(args))
                recording = fit_recording(recording, HeadRanges.of(head))  # a measurement held in its ranges
            elif is_script:
                script = load_script(args.what, library=head.expressions_path)  # its own expressions too
                if script.face_type != head.face_type:  # Face.play would refuse it once the head is open
                    raise ControllerError(
                        f"script {args.what} is for a {script.face_type} face; head {head.name!r} is {head.face_type}"
                    )
                check_script_on_head(head, script)  # every expression it plays, solved on this head's face model
            else:
                check_expression(head, args.what)  # in the head's library, and solved on its face model
            # what to play is good: the calibration next, still before anything is said, synthesised or written
            calibration = checked_calibration(args, head)
            if recording is not None:
                print("\n".join(recording.report.lines()))
            if script is not None:
                what = script
                if speaks(script):  # say cues synthesised, the sound file read: before the port is opened
                    prepared = prepare(script)
            trace_file.open()
        where = "the emulator" if args.emulate else args.port
        print(f"# opening head {head.name!r} on {where}", file=sys.stderr, flush=True)
        face = open_face(args, head, calibration)
    except StopRequested as err:
        trace_file.discard()
        print(f"servoface play: {err} during start-up; every servo left with torque off", file=sys.stderr)
        return signals.exit_code() or 130
    except open_errors() as err:
        trace_file.discard()
        print(f"servoface play: {printable(err)}", file=sys.stderr)
        return 2
    print(
        f"# playing at {args.rate:g} Hz; Ctrl-C eases to neutral and turns torque off (twice: faster)",
        file=sys.stderr,
        flush=True,
    )
    perf = None
    spoken = None
    failed = False
    code: int | None = None
    reason = "end"
    try:
        if recording is not None:
            hold_s = args.hold if args.hold is not None else (1.5 if len(recording) == 1 else 0.0)
            length_s = recording.duration_s + hold_s
            perf = face.perform(recording, length_s if args.duration is None else min(length_s, args.duration))
        elif is_script and prepared is not None:  # what Face.play does, with each sound and clock to report
            spoken = play_script_speaking(face, what, duration_s=args.duration, prepared=prepared)
            perf = spoken.performance
        elif is_script:
            perf = face.play(what, duration_s=args.duration)
        else:
            perf = face.express(args.what, hold_s=1.5 if args.hold is None else args.hold)
    except HardwareError as err:
        print(f"servoface play: bus failure: {printable(err)}", file=sys.stderr)
        failed, reason = True, "bus failure"
    except (ControllerError, SimError, ValueError) as err:
        if not (isinstance(err, ServiceClosedError) and signals.requested):  # (else a signal closed the service
            print(f"servoface play: {printable(err)}", file=sys.stderr)  # before the command got in: no error)
            code, reason = 2, f"error: {type(err).__name__}"
    except Exception as err:  # noqa: BLE001 - an unexpected error still ends in the safe stop below
        print(f"servoface play: internal error {type(err).__name__}: {printable(err)}", file=sys.stderr)
        failed, reason = True, f"error: {type(err).__name__}"
    finally:
        if signals.requested:
            reason = signals.name or "signal"
        report = face.close(reason=reason)
    if report is not None and report.reason == "bus failure":
        failed = True
    written = None
    if perf is not None:
        _summary(args, perf)
        if spoken is not None:
            print("\n".join(printable(line) for line in spoken.lines()))
        _say_unshown(face, perf, args.head)
        for trace in perf.traces:
            trace_file.sink(trace)
    written = trace_file.finish()
    print_stop("play", report)
    if written:
        print(written)
    status = exit_status(report, failed=failed, signal_code=signals.exit_code())
    return code if code is not None and status in (0, 130, 143, 129) else status


def _summary(args: argparse.Namespace, perf: Any) -> None:
    summary = perf.summary()
    loop = summary.get("loop", {})
    print(
        f"{summary['frames']} frames; verdicts {summary['verdicts']}; loop {loop.get('achieved_hz')} Hz "
        f"(target {args.rate:g}), late {loop.get('late')}, skipped {loop.get('missed')}"
    )
    reasons: dict[str, int] = {}
    for trace in perf.traces:
        for reason in trace.reasons:
            key = reason.split(":")[0]
            reasons[key] = reasons.get(key, 0) + 1
    for reason, count in sorted(reasons.items(), key=lambda kv: -kv[1])[:12]:
        print(f"  {count:5d} x {printable(reason)}")


def _say_unshown(face: object, perf: object, head_arg: str) -> None:
    """Name the AUs of what was played that move nothing on this head (the preview shows the same)."""
    from servoface.sim.au.mapping import canonical_au_name

    model = face.pipeline.face  # type: ignore[attr-defined]
    unreachable = getattr(model, "unreachable", {})
    played = {canonical_au_name(au)[0] for t in perf.traces for au, v in t.aus.items() if abs(v) > 1e-6}  # type: ignore[attr-defined]
    lost = sorted(played & set(unreachable))
    if lost:
        names = ", ".join(f"AU{n}" for n in lost)
        print(f"  this head cannot show {names} (they move nothing here): `servoface check {head_arg}` says why")
