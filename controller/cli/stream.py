"""`servoface stream --head NAME (--emulate | --port P) (--udp [HOST:]PORT | --tcp [HOST:]PORT | --stdin)`.

Follows a live stream of face data (one JSON object per datagram or line: ``{"t": 1.2, "aus": {...}}``,
``{"blendshapes": {...}, "head": {...}}``; see controller/inputs/messages.py) through the full pipeline
and prints what happened: frames, messages, bad messages, dropouts, verdicts.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from servoface.controller.cli.head_args import (
    TraceFile,
    add_head_arguments,
    checked_calibration,
    exit_status,
    open_errors,
    open_face,
    print_stop,
)
from servoface.controller.cli.input_args import add_input_arguments, load_shape_ranges
from servoface.controller.cli.terminal import printable
from servoface.controller.stop_signals import StopSignals

HELP = "follow a live face-data stream (UDP, TCP or stdin JSON) on a head, on a real port or the emulator"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_head_arguments(parser)
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--udp", metavar="[HOST:]PORT", help="JSON datagrams, e.g. 127.0.0.1:9100")
    src.add_argument("--tcp", metavar="[HOST:]PORT", help="a TCP server, one JSON object per line")
    src.add_argument("--stdin", action="store_true", help="one JSON object per line on standard input")
    parser.add_argument(
        "--allow-remote", action="store_true", help="allow binding a non-loopback address (needs a token)"
    )
    add_stream_guard_arguments(parser)
    parser.add_argument("--duration", type=float, help="seconds to follow (default: until Ctrl-C / end of stdin)")
    add_input_arguments(parser, files=False)
    parser.add_argument(
        "--arrival",
        action="store_true",
        help="with --stdin: feed each line as it arrives (default: paced by the messages' own t)",
    )
    parser.add_argument("--dropout-ms", type=float, default=250.0, help="no data for this long = dropout (250)")
    parser.add_argument(
        "--dropout",
        choices=("neutral", "hold"),
        default="neutral",
        help="in a dropout ease to neutral (default) or hold the last AUs",
    )
    parser.add_argument("--ease", type=float, default=0.5, help="seconds to ease to neutral in a dropout (0.5)")
    parser.add_argument(
        "--playout-ms",
        type=float,
        default=0.0,
        help="sample this far in the past, interpolating (evens out jitter)",
    )
    parser.add_argument("--no-smoothing", action="store_true", help="switch the One-Euro filter off")
    parser.add_argument("--min-cutoff", type=float, default=1.5, help="One-Euro cutoff at rest, Hz (1.5)")
    parser.add_argument("--beta", type=float, default=0.5, help="One-Euro speed coefficient (0.5)")
    parser.add_argument(
        "--record",
        type=Path,
        help="write every accepted message's AUs as JSON lines, timed by the messages' own t "
        "(replay: play --input FILE)",
    )


def add_stream_guard_arguments(parser: argparse.ArgumentParser) -> None:
    """Token, rate limit, TCP client limits and the control rule (controller/inputs/admission.py)."""
    group = parser.add_argument_group("stream server", "who may drive the head (README 'Inputs')")
    token = group.add_mutually_exclusive_group()
    token.add_argument("--token-file", type=Path, help="shared token: the first line of this file")
    token.add_argument("--token-env", metavar="VAR", help="shared token: the value of this environment variable")
    group.add_argument("--max-rate", type=float, default=240.0, help="messages/s per client (default 240)")
    group.add_argument("--burst", type=float, default=60.0, help="messages a client may send at once (60)")
    group.add_argument("--max-clients", type=int, default=4, help="TCP connections at once (default 4)")
    group.add_argument("--idle-timeout", type=float, default=10.0, help="close a silent TCP client after S s (10)")
    group.add_argument(
        "--takeover-s",
        type=float,
        default=1.0,
        help="another client may take control after the controller sent nothing valid for S s (1)",
    )


MAX_TOKEN_LINE = 4096  # bytes of a token file's first line


def _token(args: argparse.Namespace) -> str | None:
    import os

    from servoface.controller.inputs import InputError

    if args.token_file is not None:
        try:
            with args.token_file.open("rb") as fh:  # the first line only: never /dev/zero into memory
                first = fh.readline(MAX_TOKEN_LINE + 1)
            if len(first) > MAX_TOKEN_LINE:
                raise InputError(
                    f"--token-file {args.token_file}: its first line is longer than {MAX_TOKEN_LINE} bytes: "
                    "expected the token on its first line"
                )
            text: list[str] = first.decode("utf-8-sig").splitlines()  # a BOM (Notepad) is not the token
        except OSError as err:
            why = err.strerror or type(err).__name__
            raise InputError(
                f"--token-file {args.token_file}: cannot read it ({why}): expected a readable text file with the "
                "token on its first line"
            ) from err
        except UnicodeDecodeError as err:
            raise InputError(
                f"--token-file {args.token_file}: not UTF-8 text (byte {err.start}): expected the token on its "
                "first line"
            ) from err
        if not text or not text[0].strip():
            raise InputError(f"--token-file {args.token_file}: empty, expected the token on its first line")
        return text[0].strip()
    if args.token_env is not None:
        value = os.environ.get(args.token_env, "").strip()
        if not value:
            raise InputError(f"--token-env {args.token_env}: the variable is not set or empty")
        return value
    return None


def _fail(message: str) -> int:
    print(f"servoface stream: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    # --rate, --duration and the input options were range-checked by options.parse_command
    with StopSignals() as signals:  # SIGINT (twice: hurry to neutral), SIGTERM, SIGHUP: the stop path
        return _stream(args, signals)


def _stream(args: argparse.Namespace, signals: StopSignals) -> int:
    """Set up (interruptible until torque-on), follow on the head service, then the one stop path; exit
    status as `servoface play`'s."""
    from servoface.controller.errors import ControllerError
    from servoface.controller.inputs import (
        LineReceiver,
        MessageDecoder,
        StreamSource,
        TcpReceiver,
        UdpReceiver,
    )
    from servoface.controller.inputs.smoothing import AUSmoother
    from servoface.controller.inputs.stream import StreamRecorder
    from servoface.controller.inputs.transports import parse_address
    from servoface.controller.service import ServiceClosedError
    from servoface.controller.stop_signals import StopRequested, interruptible
    from servoface.hardware.errors import HardwareError
    from servoface.sim.errors import SimError
    from servoface.sim.heads import load_head

    trace_file = TraceFile(args.trace)
    receiver: UdpReceiver | TcpReceiver | LineReceiver | None = None
    recorder: StreamRecorder | None = None
    try:  # everything that can fail on bad arguments happens before the port opens (torque stays off)
        with interruptible():
            head = load_head(args.head)
            calibration = checked_calibration(args, head)  # before a port is bound or --record written
            decoder = MessageDecoder.for_head(  # the head's AU names, and its own ranges (values saturated)
                head,
                mirror=args.mirror,
                vergence=args.vergence,
                shape_ranges=load_shape_ranges(args),
                face_id=args.face_id or 0,
                gaze=not args.no_gaze,
                head_pose=not args.no_head_pose,
            )
            from servoface.controller.inputs.admission import StreamGuard

            guard = StreamGuard(_token(args), rate_hz=args.max_rate, burst=args.burst, takeover_s=args.takeover_s)
            smoothing = None if args.no_smoothing else AUSmoother(args.min_cutoff, args.beta)
            if args.record is not None:
                recorder = StreamRecorder(args.record)
            source = StreamSource(
                decoder,
                dropout_ms=args.dropout_ms,
                dropout=args.dropout,
                ease_s=args.ease,
                min_confidence=args.min_confidence or 0.0,
                smoothing=smoothing,
                guard=guard,
                rest_s=args.rest_s,
                on_message=recorder,
                playout_ms=args.playout_ms,
            )
            if args.udp is not None:
                host, port = parse_address(args.udp)
                receiver = UdpReceiver(source, host, port, allow_remote=args.allow_remote)
                where = f"udp {host}:{receiver.address[1]}"
            elif args.tcp is not None:
                host, port = parse_address(args.tcp)
                receiver = TcpReceiver(
                    source,
                    host,
                    port,
                    allow_remote=args.allow_remote,
                    max_clients=args.max_clients,
                    idle_timeout_s=args.idle_timeout,
                )
                where = f"tcp {host}:{receiver.address[1]}"
            else:
                receiver = LineReceiver(source, sys.stdin, pace=not args.arrival)
                where = "stdin"
            trace_file.open()
        face = open_face(args, head, calibration)
    except (StopRequested, *open_errors()) as err:  # type: ignore[misc]  # mypy cannot read a starred tuple
        if receiver is not None:
            receiver.close()
        if recorder is not None:
            recorder.close()
        trace_file.discard()
        if isinstance(err, StopRequested):
            print(f"servoface stream: {err} during start-up; every servo left with torque off", file=sys.stderr)
            return signals.exit_code() or 130
        return _fail(printable(err))
    print(
        f"following {where} on head {head.name!r} ({head.face_type}) at {args.rate:g} Hz; Ctrl-C stops",
        file=sys.stderr,
    )

    def stdin_done() -> bool:  # end of stdin and the face has eased out: nothing more will come
        if not isinstance(receiver, LineReceiver) or not receiver.eof.is_set():
            return False
        aus, in_dropout = source.target()
        return in_dropout and (args.dropout == "hold" or all(v == 0.0 for v in aus.values()))

    perf = None
    failed = False
    code: int | None = None
    reason = "end"
    try:
        with receiver:
            perf = face.follow(source, args.duration, until=stdin_done)
    except HardwareError as err:
        print(f"servoface stream: bus failure: {printable(err)}", file=sys.stderr)
        failed, reason = True, "bus failure"
    except (ControllerError, SimError, ValueError) as err:
        if not (isinstance(err, ServiceClosedError) and signals.requested):  # (else a signal closed the service
            print(f"servoface stream: {printable(err)}", file=sys.stderr)  # before the command got in: no error)
            code, reason = 2, f"error: {type(err).__name__}"
    except Exception as err:  # noqa: BLE001 - an unexpected error still ends in the safe stop below
        print(f"servoface stream: internal error {type(err).__name__}: {printable(err)}", file=sys.stderr)
        failed, reason = True, f"error: {type(err).__name__}"
    finally:
        if signals.requested:
            reason = signals.name or "signal"
        report = face.close(reason=reason)
        if recorder is not None:
            recorder.close()
    if report is not None and report.reason == "bus failure":
        failed = True
    if perf is None:
        trace_file.discard()
        print_stop("stream", report)
        status = exit_status(report, failed=True, signal_code=signals.exit_code())
        return code if code is not None and status in (0, 130, 143, 129) else status
    summary = perf.summary()
    loop = summary.get("loop", {})
    stats = source.stats
    print(
        f"{summary['frames']} frames; loop {loop.get('achieved_hz')} Hz (target {args.rate:g}), "
        f"late {loop.get('late')}, skipped {loop.get('missed')}"
    )
    print(
        f"messages {stats.messages}: good {stats.good}, bad {stats.bad}, out of order {stats.out_of_order}, "
        f"low confidence {stats.low_confidence}; dropouts {stats.dropouts} "
        f"({stats.samples_in_dropout} frames in dropout); newest-message age max "
        f"{1e3 * stats.latency_s_max:.1f} ms (mean {1e3 * stats.age_s.mean:.1f} ms)"
    )
    print(f"verdicts {summary['verdicts']}")
    if decoder.clamped:
        print(f"{decoder.clamped} blendshape scores slightly outside 0..1 clamped (tolerance 0.1)")
    if decoder.saturated and decoder.head_ranges is not None:
        print(decoder.head_ranges.describe(decoder.saturated))
    if stats.rest:
        print(f"{stats.rest} ({stats.calibrating} messages taken as the rest pose, not shown)")
    if args.stdin:
        print(f"stdin {'fed on arrival' if args.arrival else 'paced by the messages t'}")
    else:
        g = guard.stats
        print(
            f"refused: {g.unauthenticated} without the token, {g.rate_limited} over the rate limit, "
            f"{g.not_controlling} from a client without control (control changed {g.control_changes} x); "
            f"superseded {stats.superseded}"
            + (
                f"; tcp connections {g.connections}: {g.idle_closed} closed idle, {g.evicted} evicted at the "
                f"cap of {args.max_clients}, {g.lines_too_long} lines too long"
                if args.tcp is not None
                else ""
            )
        )
    for error in list(stats.errors)[-5:]:
        print(f"  bad: {printable(error)}")
    if recorder is not None:
        print(f"{recorder.count} messages recorded to {recorder.path} (replay: servoface play --input FILE)")
    for trace in perf.traces:
        trace_file.sink(trace)
    written = trace_file.finish()
    print_stop("stream", report)
    if written:
        print(written)
    status = exit_status(report, failed=failed, signal_code=signals.exit_code())
    return code if code is not None and status in (0, 130, 143, 129) else status
