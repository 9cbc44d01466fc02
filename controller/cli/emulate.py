"""`servoface emulate --ids 1-24 --model XL330-M288 --baud 1000000 [--no-wire-time]`: serve an emulated chain.

Prints the pseudo-terminal path as the first line of output, then serves until Ctrl-C or SIGTERM (exit 0).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import Any

HELP = "serve an emulated Dynamixel chain on a pseudo-terminal (prints its path first)"


def parse_ids(text: str) -> list[int]:
    """``"1-4,7,10-12"`` -> [1, 2, 3, 4, 7, 10, 11, 12]; raises ValueError naming the bad part."""
    ids: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            raise ValueError(f"empty element in id list {text!r}")
        if "-" in part:
            lo_text, _, hi_text = part.partition("-")
            try:
                lo, hi = int(lo_text), int(hi_text)
            except ValueError:
                raise ValueError(f"id range {part!r}: expected two integers like 1-24") from None
            if lo > hi:
                raise ValueError(f"id range {part!r}: start must not exceed end")
            ids.extend(range(lo, hi + 1))
        else:
            try:
                ids.append(int(part))
            except ValueError:
                raise ValueError(f"id {part!r}: expected an integer or a range like 1-24") from None
    bad = [i for i in ids if not 0 <= i <= 252]
    if bad:
        raise ValueError(f"ids {bad}: expected 0..252")
    if len(set(ids)) != len(ids):
        raise ValueError(f"id list {text!r} names some id twice")
    return ids


def _ids_type(text: str) -> list[int]:
    try:
        return parse_ids(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--ids",
        type=_ids_type,
        default=parse_ids("1-24"),
        help="servo ids: ranges and lists, e.g. 1-4,7,10-12 (default 1-24)",
    )
    parser.add_argument(
        "--model",
        default="XL330-M288",
        help="servo model: XL330-M288, XL430-W250, XM430-W350 or MX-28(2.0) (default XL330-M288)",
    )
    parser.add_argument("--baud", type=int, default=1_000_000, help="bus baud rate in bps (default 1000000)")
    parser.add_argument("--no-wire-time", action="store_true", help="answer at once instead of at wire speed")
    parser.add_argument(
        "--head",
        help="emulate this head's chain instead (built-in name or profile folder): its ids and models, each "
        "servo at rest at its calibration's neutral tick (overrides --ids/--model)",
    )
    parser.add_argument(
        "--fault-on-signal",
        action="append",
        default=[],
        metavar="ID:KIND[:DELAY_S]",
        help="on SIGUSR1, start fault KIND (no_reply, late_reply, corrupt_crc, overload, ...) on servo ID "
        "until the end (repeatable; tests use it to break a servo at a chosen moment)",
    )
    parser.add_argument(
        "--state-file",
        type=Path,
        help="on exit, write every servo's final state (torque, goal, present, watchdog, error) and every "
        "Goal Position / Torque Enable decoded from the wire as JSON here (tests check from this side)",
    )


def chain_state(chain: Any) -> dict[str, Any]:
    """The emulated servos as the far end of the wire sees them, JSON-ready."""
    servos = {}
    for sid in chain.ids:
        servo = chain.servo(sid)
        servos[str(sid)] = {
            "torque_enable": servo.read_register("Torque Enable"),
            "goal_position": servo.read_register("Goal Position"),
            "present_position": servo.position_tick,
            "bus_watchdog": servo.read_register("Bus Watchdog"),
            "hardware_error_status": servo.hardware_error,
            "moving": servo.read_register("Moving"),
            "min_position_limit": servo.read_register("Min Position Limit"),
            "max_position_limit": servo.read_register("Max Position Limit"),
        }
    return {
        "t_s": chain.time_s,
        "servos": servos,
        "goal_writes": [[round(t, 6), sid, tick] for t, sid, tick in chain.goal_writes()],
        "torque_writes": [[round(t, 6), sid, v] for t, sid, v in chain.register_writes(64, 1)],
    }


def _parse_fault(text: str) -> tuple[int, str, float]:
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise ValueError(f"{text!r}: expected ID:KIND or ID:KIND:DELAY_S")
    try:
        sid = int(parts[0])
        delay = float(parts[2]) if len(parts) == 3 else 0.010
    except ValueError:
        raise ValueError(f"{text!r}: ID must be an integer and DELAY_S a number") from None
    from servoface.hardware.emulator.faults import KINDS

    if parts[1] not in KINDS:
        raise ValueError(f"{text!r}: unknown fault {parts[1]!r}; expected one of {sorted(KINDS)}")
    return sid, parts[1], delay


def _head_chain(args: argparse.Namespace) -> tuple[Any, dict[int, int]]:
    from servoface.controller.face import head_calibration
    from servoface.controller.head_servos import servo_specs
    from servoface.hardware.emulator import ServoChain
    from servoface.sim.heads import load_head

    head = load_head(args.head)
    cal = head_calibration(head)
    specs = servo_specs(head, cal)
    chain = ServoChain.create([(s.servo_id, s.model) for s in specs], baud=args.baud, wire_time=not args.no_wire_time)
    return chain, {s.servo_id: cal.by_id(s.servo_id).neutral_tick for s in specs}


def write_state(chain: Any, path: Path) -> None:
    from servoface.calibration.fileformat import write_atomic

    write_atomic(path, json.dumps(chain_state(chain)))


def run(args: argparse.Namespace) -> int:
    from servoface.hardware.emulator import EmulatorError, ServoChain

    try:
        faults = [_parse_fault(text) for text in args.fault_on_signal]
    except ValueError as err:
        print(f"servoface emulate: --fault-on-signal: {err}", file=sys.stderr)
        return 2
    try:
        if args.head is not None:
            chain, rest = _head_chain(args)
        else:
            chain = ServoChain.create(ids=args.ids, model=args.model, baud=args.baud, wire_time=not args.no_wire_time)
            rest = {}
        for sid, tick in rest.items():
            chain.servo(sid).move_by_hand(tick)
    except EmulatorError as err:
        print(f"servoface emulate: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # noqa: BLE001 - a bad head profile or calibration: reported, no traceback
        print(f"servoface emulate: --head {args.head}: {err}", file=sys.stderr)
        return 2
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    def on_fault_signal(signum: int, frame: FrameType | None) -> None:
        for sid, kind, delay in faults:
            chain.faults.inject_now(sid, kind, delay_s=delay)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    previous[signal.SIGUSR1] = signal.signal(signal.SIGUSR1, on_fault_signal)
    try:
        with chain:
            try:
                path = chain.serve_pty()
            except EmulatorError as err:
                print(f"servoface emulate: {err}", file=sys.stderr)
                return 1
            print(path, flush=True)
            print(
                f"# serving {len(chain.ids)} x {args.model if args.head is None else 'servos of ' + args.head} "
                f"at {args.baud} bps"
                f"{' (no wire time)' if args.no_wire_time else ''}; Ctrl-C to stop",
                file=sys.stderr,
                flush=True,
            )
            while not stop.wait(0.2):
                pass
            if args.state_file is not None:
                write_state(chain, args.state_file)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    return 0
