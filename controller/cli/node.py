"""`servoface node --head H --name NAME [--site SITE] (--port P | --emulate) [--listen EP] [--connect EP]`."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from servoface.controller.cli.head_args import add_read_arguments, read_options
from servoface.controller.cli.network_args import add_network_arguments, open_from_args

if TYPE_CHECKING:
    from servoface.calibration import HeadCalibration
    from servoface.sim.head import Head

HELP = "serve a head on Zenoh (servoface/<site>/<name>/...): commands, AU streams, state, status, presence"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--head", default="human", help="built-in head (human, dog) or a profile folder")
    parser.add_argument("--name", required=True, help="this head's name on the network (a-z, 0-9, _ -)")
    parser.add_argument("--site", default="default", help="site (a group of heads), default 'default'")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--port", help="serial port of the chain")
    where.add_argument("--emulate", action="store_true", help="an in-process emulated chain")
    parser.add_argument("--baud", type=int, default=1_000_000, help="bus speed (default 1000000)")
    parser.add_argument("--rate", type=float, default=50.0, help="control rate in Hz (default 50)")
    add_read_arguments(parser)
    parser.add_argument(
        "--hold-on-link-loss",
        action="store_true",
        help="keep the pose when the last peer disconnects (default: ease to neutral)",
    )
    parser.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    parser.add_argument(
        "--wire-log",
        type=Path,
        default=None,
        help="with --emulate: append every goal the emulated servos receive to this file as JSON "
        "lines [monotonic_s, id, tick], as they arrive (for tests)",
    )
    add_network_arguments(parser, node=True)


def run(args: argparse.Namespace) -> int:
    from servoface.controller.errors import ControllerError
    from servoface.controller.network.errors import NetworkError
    from servoface.controller.network.keys import head_keys
    from servoface.controller.network.node import HeadNode
    from servoface.controller.service import HeadService, open_head
    from servoface.hardware.errors import HardwareError
    from servoface.sim.errors import SimError

    # --rate was range-checked by options.parse_command
    try:
        keys = head_keys(args.site, args.name)
    except NetworkError as err:
        print(f"servoface node: {err}", file=sys.stderr)
        return 2
    checked = _checked_head(args)  # before the session starts: a broken profile is refused with nothing up
    if isinstance(checked, int):
        return checked
    head, calibration = checked
    try:
        session = open_from_args(args, node=True, keys=keys)
    except NetworkError as err:
        print(f"servoface node: {err}", file=sys.stderr)
        return 2
    stop = threading.Event()

    def on_signal(signum: int, _frame: object) -> None:
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, on_signal)
    try:
        opened = open_head(
            head,
            calibration=calibration,
            port=args.port,
            emulate=args.emulate,
            baud=args.baud,
            rate_hz=args.rate,
            **read_options(args),
        )
    except (ControllerError, SimError, HardwareError, OSError, ValueError) as err:
        session.close()
        print(f"servoface node: {err}", file=sys.stderr)
        return 2
    service = HeadService(opened.head, opened.pipeline, start=False, name=f"servoface-{args.name}")
    # frames on a grid of the machine's monotonic clock: heads on one machine (or NTP-disciplined ones)
    # tick together, so a cue lands on the same frame everywhere
    period = 1.0 / args.rate
    now = time.monotonic()
    time.sleep(period - (now % period))
    service.start()
    node = HeadNode(
        service,
        session,
        keys,
        hold_on_link_loss=args.hold_on_link_loss,
        on_event=lambda msg: print(f"node {keys.base}: {msg}", flush=True),
    ).start()
    wire_log = None
    if args.wire_log is not None and opened.chain is not None:
        wire_log = _WireLog(opened.chain, args.wire_log, stop)
    listen = args.listen or ["tcp/127.0.0.1:7447"]
    print(
        f"node {keys.base} ({opened.head.name}, {opened.head.face_type}) listening on {', '.join(listen)}", flush=True
    )
    code = 0
    try:
        deadline = None if args.duration is None else time.monotonic() + args.duration
        while not stop.wait(0.1):
            if deadline is not None and time.monotonic() >= deadline:
                break
            if not service.running:
                print(f"servoface node: the head service stopped ({service.error})", file=sys.stderr)
                code = 1
                break
    finally:
        node.close()
        report = service.shutdown()
        print(f"node {keys.base}: stopped; {json.dumps(node.guard.counters())}; link losses {node.link_losses}")
        for line in [] if report is None else report.lines():  # how the head ended: eased, torque off
            print(line, flush=True)
        if report is not None and getattr(report, "unreached", None):
            print(f"servoface node: torque could not be turned off on {report.unreached}", file=sys.stderr)
            code = 1
        if wire_log is not None:
            wire_log.close()
        if opened.chain is not None:
            opened.chain.close()
        session.close()
    return code


def _checked_head(args: argparse.Namespace) -> tuple[Head, HeadCalibration] | int:
    """The head and its calibration, loaded and checked as `open_head` would find them (the profile, its
    calibration file against its servos, its face model and its library's face type), or the exit code 2 after
    one line saying what is wrong. Every expression of its library is solved on its face model too (a peer may
    ask for any of them): one the head refuses is a warning line, not a refusal."""
    from servoface.calibration import CalibrationError
    from servoface.controller.cli.head_args import check_on_head, checked_calibration
    from servoface.controller.cli.terminal import printable
    from servoface.controller.errors import ControllerError
    from servoface.sim.errors import HeadProfileError, SimError
    from servoface.sim.expressions import load_library
    from servoface.sim.heads import load_head

    try:
        head = load_head(args.head)
    except (HeadProfileError, FileNotFoundError, KeyError, ValueError) as err:
        from servoface.controller.cli.exits import head_message

        print(f"servoface node: {printable(head_message(args.head, err))}", file=sys.stderr)
        return 2
    from servoface.sim.errors import ExpressionError
    from servoface.sim.face_model import FaceModel

    try:
        calibration = checked_calibration(args, head)  # (node takes no --calibration: the profile's own)
        library = load_library(head.expressions_path or head.face_type)
        model = FaceModel(head)  # the profile's AU table, direct table and muscles: a broken one refuses here
        check_on_head(head, library, [], model=model)  # a library of another face type is refused too
    except (SimError, CalibrationError, ControllerError, OSError) as err:
        print(f"servoface node: {printable(err)}", file=sys.stderr)
        return 2
    for name in library:  # one expression the head cannot show does not stop the node: a peer asking for it
        try:  # is refused at once (`HeadService.express`); said here, once, before the session starts
            check_on_head(head, library, [name], model=model)
        except ExpressionError as err:
            print(f"servoface node: warning: {printable(err)}; a peer asking for it is refused", file=sys.stderr)
    return head, calibration


class _WireLog:
    """Appends the emulated chain's decoded goal writes to a file every 50 ms (monotonic time)."""

    def __init__(self, chain: object, path: Path, stop: threading.Event) -> None:
        self.chain, self.path, self.stop = chain, path, stop
        self.offset = time.monotonic() - chain._clock()  # type: ignore[attr-defined]  # noqa: SLF001
        self.done = 0
        self.fh = path.open("w")
        self.thread = threading.Thread(target=self._run, name="servoface-wire-log", daemon=True)
        self.thread.start()

    def _flush(self) -> None:
        """Decode only the packets logged since the last flush (decoding the whole log every 50 ms grew
        with the run and cost the node as much CPU as its head loop: late frames in the benches)."""
        from servoface.hardware.emulator.chain import GOAL_ADDRESS
        from servoface.hardware.emulator.packet_log import register_writes

        log = self.chain.log  # type: ignore[attr-defined]  # a PacketLog: absolute indexes survive its trims
        end = len(log)
        new = log[self.done : end]
        self.done = end
        lines = [
            json.dumps([round(t_s + self.offset, 6), sid, tick])
            for t_s, sid, tick in register_writes(new, GOAL_ADDRESS, 4)
        ]
        if lines:
            self.fh.write("\n".join(lines) + "\n")
        self.fh.flush()

    def _run(self) -> None:
        while not self.stop.wait(0.05):
            self._flush()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(1.0)
        self._flush()
        self.fh.close()
