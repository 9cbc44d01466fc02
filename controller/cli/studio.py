"""`servoface studio --head NAME|PATH (--port P | --emulate) [--host 127.0.0.1] [--port-http N] [--allow-remote]`

Starts the head service on the head and serves the studio (a browser app: live sliders and the twin,
servos, calibration, authoring) on loopback. Prints the URL with this run's token and opens nothing.
Ctrl-C / SIGTERM / SIGHUP end it through the service's safe stop (ease to neutral, torque off)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from servoface.controller.cli.head_args import add_read_arguments, read_options

if TYPE_CHECKING:
    from servoface.controller.stop_signals import StopSignals

HELP = "serve the studio (browser app) for a head: live AUs and twin, servos, calibration, authoring"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--head", required=True, help="built-in head (human, dog) or a profile folder")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--port", help="serial port of the chain, e.g. /dev/ttyUSB0 (or a pty from `servoface emulate`)")
    where.add_argument("--emulate", action="store_true", help="run on an in-process emulated chain")
    parser.add_argument("--baud", type=int, default=1_000_000, help="bus speed in bps (default 1000000)")
    parser.add_argument("--rate", type=float, default=50.0, help="control rate in Hz (default 50)")
    parser.add_argument("--calibration", type=Path, help="calibration JSON (default: the one the profile names)")
    add_read_arguments(parser)
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1, loopback)")
    parser.add_argument("--port-http", type=int, default=8765, help="HTTP port (default 8765; 0 = any free one)")
    parser.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a non-loopback --host (the token is still required; anyone who has it can move the head)",
    )
    parser.add_argument(
        "--allow-origin",
        action="append",
        default=[],
        metavar="ORIGIN",
        help="another browser origin allowed to use the API (e.g. http://robot.local:8765); repeatable",
    )
    parser.add_argument("--out-dir", type=Path, default=Path.cwd(), help="where calibrations are written (default .)")
    parser.add_argument(
        "--scripts-dir", type=Path, default=Path.cwd(), help="where scripts are read and saved (default .)"
    )
    parser.add_argument("--no-render", action="store_true", help="no twin renders (a machine without EGL)")


def run(args: argparse.Namespace) -> int:
    from servoface.controller.stop_signals import StopSignals

    with StopSignals() as signals:  # SIGINT (twice: hurry to neutral), SIGTERM, SIGHUP: the one stop path
        return _studio(args, signals)


class _Wake:
    """Wakes the main thread's wait when a stop signal comes (`StopSignals.watching`)."""

    def __init__(self) -> None:
        import threading

        self.event = threading.Event()

    def stop(self) -> None:
        self.event.set()


def _studio(args: argparse.Namespace, signals: StopSignals) -> int:
    from servoface.controller.cli.head_args import checked_calibration, open_errors
    from servoface.controller.cli.terminal import printable
    from servoface.controller.service import HeadService, open_head
    from servoface.controller.stop_signals import StopRequested, interruptible
    from servoface.controller.studio import StudioError, StudioOptions, StudioServer
    from servoface.controller.studio.security import is_loopback
    from servoface.sim.heads import load_head

    # every message shows what came from outside (a path, a file's contents, a host) through `printable`:
    # an escape sequence in a file name must not repaint the operator's terminal
    if not is_loopback(args.host) and not args.allow_remote:
        print(
            f"servoface studio: --host {printable(args.host)} is not loopback; add --allow-remote to serve it",
            file=sys.stderr,
        )
        return 2
    # --port-http and --rate were range-checked by options.parse_command
    for name in ("out_dir", "scripts_dir"):
        folder = getattr(args, name)
        if not folder.is_dir():
            print(f"servoface studio: --{name.replace('_', '-')} {printable(folder)}: not a folder", file=sys.stderr)
            return 2
    taken = _port_taken(args.host, args.port_http)
    if taken is not None:  # before the head is opened: a taken port must not switch torque on
        print(
            f"servoface studio: --port-http {args.port_http}: cannot listen on {printable(args.host)}:{args.port_http} "
            f"({printable(taken)}); is another studio running? choose another port, or 0 for any free one",
            file=sys.stderr,
        )
        return 2
    try:
        with interruptible():  # torque off, no bus traffic yet: a signal ends the start-up at once
            head = load_head(args.head)
            calibration = checked_calibration(args, head)  # a file of another head names itself, as in play
            opened = open_head(
                head, port=args.port, emulate=args.emulate, baud=args.baud, rate_hz=args.rate,
                calibration=calibration, **read_options(args),
            )  # fmt: skip
    except StopRequested as err:
        print(f"servoface studio: {printable(err)} during start-up; every servo left with torque off", file=sys.stderr)
        return signals.exit_code() or 130
    except open_errors() as err:
        print(f"servoface studio: {printable(err)}", file=sys.stderr)
        return 2
    service = HeadService(opened.head, opened.pipeline)
    options = StudioOptions(out_dir=args.out_dir, scripts_dir=args.scripts_dir, render=not args.no_render)
    server = None
    code = 0
    wake = _Wake()
    try:
        with signals.watching(wake):  # handlers never raise from here on: they ask for the stop, and a
            # second signal hurries the ease (the service's shutdown reads `StopSignals.hurry`)
            server = StudioServer(
                service, host=args.host, port=args.port_http, allow_remote=args.allow_remote, options=options,
                allow_origins=frozenset(args.allow_origin),
            )  # fmt: skip
            server.start()
            where = "emulated chain" if args.emulate else args.port
            print(f"servoface studio: head '{printable(opened.head.name)}' on {printable(where)}", flush=True)
            print(f"open {server.url}", flush=True)
            print("Ctrl-C to stop (the head eases to neutral, torque off)", flush=True)
            while not wake.event.wait(0.2) and server.running:
                pass
    except (StudioError, OSError) as err:
        print(f"servoface studio: {printable(err)}", file=sys.stderr)
        code = 2
    finally:
        if server is not None:
            server.stop()
        report = service.shutdown(reason=signals.name or "end")
        if opened.chain is not None:
            opened.chain.close()
    for line in report.lines():
        print(printable(line), flush=True)
    if not report.torque_off:
        return 3
    return code or (signals.exit_code() or 0)


def _port_taken(host: str, port: int) -> str | None:
    """Why ``host:port`` cannot be listened on now (as the server will bind it), or None (0: any free port)."""
    import socket

    if port == 0:
        return None
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as err:
            return err.strerror or str(err)
    return None
