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
    exit_status,
    open_errors,
    open_face,
    print_stop,
    rate_problem,
)
from servoface.controller.cli.terminal import printable
from servoface.controller.stop_signals import StopSignals

HELP = "follow a live face-data stream (UDP, TCP or stdin JSON) on a head, on a real port or the emulator"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_head_arguments(parser)
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--udp", metavar="[HOST:]PORT", help="JSON datagrams, e.g. 127.0.0.1:9100")
    src.add_argument("--tcp", metavar="[HOST:]PORT", help="a TCP server, one JSON object per line")
    src.add_argument("--stdin", action="store_true", help="one JSON object per line on standard input")
    parser.add_argument("--allow-remote", action="store_true", help="allow binding a non-loopback address")
    parser.add_argument("--duration", type=float, help="seconds to follow (default: until Ctrl-C / end of stdin)")
    parser.add_argument("--mirror", action="store_true", help="imitate a person facing the robot (swap L/R)")
    parser.add_argument("--vergence", action="store_true", help="map eye look differences to AU65/66")
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
    parser.add_argument("--min-confidence", type=float, default=0.0, help="ignore messages below this confidence")
    parser.add_argument(
        "--shape-ranges",
        type=Path,
        help="per-user blendshape rest/full ranges JSON (controller/inputs/shape_ranges.py)",
    )
    parser.add_argument("--no-smoothing", action="store_true", help="switch the One-Euro filter off")
    parser.add_argument("--min-cutoff", type=float, default=1.5, help="One-Euro cutoff at rest, Hz (1.5)")
    parser.add_argument("--beta", type=float, default=0.5, help="One-Euro speed coefficient (0.5)")
    parser.add_argument(
        "--record",
        type=Path,
        help="write every accepted message's AUs as JSON lines (replay: play --input FILE)",
    )


def _fail(message: str) -> int:
    print(f"servoface stream: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    if (problem := rate_problem(args)) is not None:
        return _fail(problem)
    if args.duration is not None and not (0 < args.duration < 1e7):
        return _fail(f"--duration must be a positive number of seconds, got {args.duration}")
    if not 0.0 <= args.min_confidence <= 1.0:
        return _fail(f"--min-confidence must be within 0..1, got {args.min_confidence}")
    with StopSignals() as signals:  # SIGINT (once: ease then torque off; twice: torque off now), SIGTERM, SIGHUP
        return _stream(args, signals)


def _stream(args: argparse.Namespace, signals: StopSignals) -> int:
    from servoface.controller.errors import ControllerError
    from servoface.controller.frame import FrameValidator
    from servoface.controller.inputs import (
        LineReceiver,
        MessageDecoder,
        StreamSource,
        TcpReceiver,
        UdpReceiver,
    )
    from servoface.controller.inputs.follow import follow
    from servoface.controller.inputs.smoothing import AUSmoother
    from servoface.controller.inputs.stream import StreamRecorder
    from servoface.controller.inputs.transports import parse_address
    from servoface.controller.safe_stop import bus_problem
    from servoface.controller.stop_signals import StopRequested, interruptible
    from servoface.hardware.errors import HardwareError
    from servoface.sim.errors import SimError
    from servoface.sim.heads import load_head

    receiver: UdpReceiver | TcpReceiver | LineReceiver | None = None
    recorder: StreamRecorder | None = None
    trace_file = TraceFile(args.trace)
    try:  # everything that can fail on bad arguments happens before the port opens (torque stays off)
        with interruptible():
            head = load_head(args.head)
            validator = FrameValidator.for_head(head)
            ranges = None
            if args.shape_ranges is not None:
                from servoface.controller.inputs import ShapeRanges, load_blendshape_map

                ranges = ShapeRanges.load(args.shape_ranges, load_blendshape_map().names)
            decoder = MessageDecoder(
                head.face_type,
                allowed=validator.allowed,
                mirror=args.mirror,
                vergence=args.vergence,
                shape_ranges=ranges,
            )
            smoothing = None if args.no_smoothing else AUSmoother(args.min_cutoff, args.beta)
            trace_file.open()
            if args.record is not None:
                recorder = StreamRecorder(args.record)
            source = StreamSource(
                decoder,
                dropout_ms=args.dropout_ms,
                dropout=args.dropout,
                ease_s=args.ease,
                min_confidence=args.min_confidence,
                smoothing=smoothing,
                on_message=recorder,
                playout_ms=args.playout_ms,
            )
            if args.udp is not None:
                host, port = parse_address(args.udp)
                receiver = UdpReceiver(source, host, port, allow_remote=args.allow_remote)
                where = f"udp {host}:{receiver.address[1]}"
            elif args.tcp is not None:
                host, port = parse_address(args.tcp)
                receiver = TcpReceiver(source, host, port, allow_remote=args.allow_remote)
                where = f"tcp {host}:{receiver.address[1]}"
            else:
                receiver = LineReceiver(source, sys.stdin)
                where = "stdin"
        face = open_face(args, head)
    except (StopRequested, *open_errors()) as err:
        if receiver is not None:
            receiver.close()
        if recorder is not None:
            recorder.close()
        trace_file.finish()
        if isinstance(err, StopRequested):
            print(f"servoface stream: {err} during start-up; every servo left with torque off", file=sys.stderr)
            return signals.exit_code() or 130
        return _fail(printable(err))
    if trace_file.writer is not None:
        face.traces.sink = trace_file.sink
    print(
        f"following {where} on head {head.name!r} ({head.face_type}) at {args.rate:g} Hz; Ctrl-C stops",
        file=sys.stderr,
    )

    def stdin_done() -> bool:  # end of stdin and the face has eased out: nothing more will come
        if not isinstance(receiver, LineReceiver) or not receiver.eof.is_set():
            return False
        aus, in_dropout = source.target()
        return in_dropout and (args.dropout == "hold" or all(v == 0.0 for v in aus.values()))

    def stop_now() -> bool:
        return stdin_done() or bus_problem(face.pipeline.last_snapshot) is not None

    perf = None
    failed = False
    code: int | None = None
    reason = "end"
    try:
        with receiver:
            perf = follow(
                face.pipeline,
                source,
                args.duration,
                on_frame=face.traces.append,
                until=stop_now,
                keep_traces=True,
                stop_on_interrupt=True,
            )
    except (ControllerError, SimError, ValueError) as err:
        print(f"servoface stream: {printable(err)}", file=sys.stderr)
        code, reason = 2, f"error: {type(err).__name__}"
    except HardwareError as err:
        print(f"servoface stream: bus failure: {printable(err)}", file=sys.stderr)
        failed, reason = True, "bus failure"
    except Exception as err:  # noqa: BLE001 - an unexpected error still ends in the safe stop below
        print(f"servoface stream: internal error {type(err).__name__}: {printable(err)}", file=sys.stderr)
        failed, reason = True, f"error: {type(err).__name__}"
    finally:
        problem = bus_problem(face.pipeline.last_snapshot)
        if signals.requested:
            reason = signals.name or "signal"
        elif problem is not None:
            reason = "bus failure"
        report = face.close(reason=reason)
        written = trace_file.finish()
        if recorder is not None:
            recorder.close()
    if problem is not None:
        failed = True
        print(f"servoface stream: stopped early: {problem}", file=sys.stderr)
    if perf is None:
        print_stop("stream", report)
        return exit_status(report, failed=True, signal_code=signals.exit_code()) if code is None else code
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
    for error in list(stats.errors)[-5:]:
        print(f"  bad: {printable(error)}")
    if recorder is not None:
        print(f"{recorder.count} messages recorded to {recorder.path} (replay: servoface play --input FILE)")
    print_stop("stream", report)
    if written:
        print(written)
    status = exit_status(report, failed=failed, signal_code=signals.exit_code())
    return code if code is not None and status in (0, 130, 143, 129) else status
