"""`servoface emulate`: serve an emulated chain on a pseudo-terminal (prints its path first).

    servoface emulate --head human                        # exactly the head's servos (ids, models), at rest
    servoface emulate --servos 1-17:XL330-M288,18-21:XL430-W250
    servoface emulate --ids 1-24 --model XL330-M288 --baud 1000000 [--no-wire-time] [--realism]
    servoface emulate --head dog --fault 3:no_reply@2s+0.5s --fault 5:overload@10s

Prints the pseudo-terminal path as the first line of output, then serves until Ctrl-C or SIGTERM (exit 0).
Fault times count from when serving starts. A profile not calibrated yet (right after `servoface new`) is
served all the same, every servo at tick 2048, so calibration can be rehearsed on the emulator; a calibration
file that is there but broken is refused (exit 2).
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

from servoface.controller.cli.emulate_args import FaultSpec, parse_fault, parse_ids, parse_servos

HELP = "serve an emulated Dynamixel chain on a pseudo-terminal (prints its path first)"
__all__ = ["HELP", "add_arguments", "parse_ids", "run"]


def _typed(parse: Any) -> Any:
    def convert(text: str) -> Any:
        try:
            return parse(text)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None

    return convert


def add_arguments(parser: argparse.ArgumentParser) -> None:
    chain = parser.add_mutually_exclusive_group()
    chain.add_argument("--head", help="serve exactly this head's servos: a built-in name (human, dog) or a profile")
    chain.add_argument(
        "--servos",
        type=_typed(parse_servos),
        help="a mixed chain: IDS:MODEL groups, e.g. 1-17:XL330-M288,18-21:XL430-W250",
    )
    chain.add_argument("--ids", type=_typed(parse_ids), help="servo ids of one model: e.g. 1-4,7,10-12 (default 1-24)")
    parser.add_argument(
        "--model",
        default=None,
        help="model for --ids: XL330-M288 (default), XL430-W250, XM430-W350 or MX-28(2.0)",
    )
    parser.add_argument("--baud", type=int, default=1_000_000, help="bus baud rate in bps (default 1000000)")
    parser.add_argument("--no-wire-time", action="store_true", help="answer at once instead of at wire speed")
    parser.add_argument(
        "--fault",
        action="append",
        default=[],
        type=_typed(parse_fault),
        metavar="ID:KIND[*N][@START[+DURATION]]",
        help="script a fault (repeatable), e.g. 3:no_reply@2s+0.5s, 5:late_reply=20ms@1s, 2:overload@3s, "
        "3:no_reply*1 (only servo 3's next reply lost)",
    )
    parser.add_argument(
        "--realism", action="store_true", help="non-ideal servos: backlash, settling error and lag, encoder noise"
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed of --realism's noise (default 0)")
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
        "Goal Position / Torque Enable decoded from the wire, and packets per instruction code, as JSON here "
        "(tests check from this side)",
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
        "packets_received": len(chain.log),  # every instruction packet the chain ever got (CRC valid)
        "instruction_counts": _instruction_counts(chain),
        "read_addresses": _read_addresses(chain),
        "indirect_address_writes": _indirect_address_writes(chain),
        "servos": servos,
        "goal_writes": [[round(t, 6), sid, tick] for t, sid, tick in chain.goal_writes()],
        "torque_writes": [[round(t, 6), sid, v] for t, sid, v in chain.register_writes(64, 1)],
    }


def _instruction_counts(chain: Any) -> dict[str, int]:
    """How many packets of each instruction code (``"0x8A"``: Fast Sync Read) the packet log still holds."""
    from collections import Counter

    counts = Counter(entry.instruction for entry in chain.log.kept())
    return {f"0x{code:02X}": n for code, n in sorted(counts.items())}


def _read_addresses(chain: Any) -> dict[str, int]:
    """How many (Fast) Sync Reads (0x82, 0x8A) the packet log holds per start address (``"224"``: through the
    position sentinel's Indirect Data; ``"132"``: Present Position read directly)."""
    from collections import Counter

    from servoface.hardware.emulator.packet import Instruction

    reads = (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ)
    counts = Counter(
        entry.params[0] | entry.params[1] << 8
        for entry in chain.log.kept()
        if entry.instruction in reads and len(entry.params) >= 4
    )
    return {str(address): n for address, n in sorted(counts.items())}


def _indirect_address_writes(chain: Any) -> int:
    """How many writes (any write instruction, per servo) the packet log holds to an Indirect Address slot of
    the base table (168..223, 2 bytes each: XL330's 20 slots are 168..207)."""
    from servoface.hardware.emulator.packet_log import register_writes

    kept = chain.log.kept()
    return len({(t, sid) for address in range(168, 224, 2) for t, sid, _ in register_writes(kept, address, 2)})


def write_state(chain: Any, path: Path) -> None:
    from servoface.calibration.fileformat import write_atomic

    write_atomic(path, json.dumps(chain_state(chain)))


def _parse_signal_fault(text: str) -> tuple[int, str, float]:
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise ValueError(f"--fault-on-signal {text!r}: expected ID:KIND or ID:KIND:DELAY_S")
    try:
        sid = int(parts[0])
        delay = float(parts[2]) if len(parts) == 3 else 0.010
    except ValueError:
        raise ValueError(f"--fault-on-signal {text!r}: ID must be an integer and DELAY_S a number") from None
    from servoface.hardware.emulator.faults import KINDS

    if parts[1] not in KINDS:
        raise ValueError(f"--fault-on-signal {text!r}: unknown fault {parts[1]!r}; expected one of {sorted(KINDS)}")
    return sid, parts[1], delay


UNCALIBRATED_REST_TICK = 2048  # the middle of every supported model's 0..4095 position range


def _head_chain(name: str) -> tuple[list[tuple[int, str]], dict[int, int], str | None]:
    """(id, model) of every servo of head ``name``, their rest ticks (the calibration's neutral ticks, or
    the middle of the position range for a profile not calibrated yet) and, for the latter, a note saying
    so and how to calibrate (``{pty}``: where the pty path goes). A calibration file that exists but is
    broken raises CalibrationError."""
    from servoface.controller.face import head_calibration
    from servoface.controller.head_servos import driver_model_name
    from servoface.sim.heads import load_head

    head = load_head(name)
    pairs = [(a.servo.id, driver_model_name(a.servo.model)) for a in head.actuators]
    path = head.calibration_path
    if path is None or not Path(path).exists():  # right after `servoface new`: rehearse calibration here
        where = "names no calibration file" if path is None else f"has no {path} yet"
        note = (
            f"head {head.name!r} is not calibrated ({where}): its servos wait at tick "
            f"{UNCALIBRATED_REST_TICK}; calibrate with `servoface calibrate --head {name} --port {{pty}}`"
        )
        return pairs, {sid: UNCALIBRATED_REST_TICK for sid, _ in pairs}, note
    cal = head_calibration(head)
    neutral = {sid: cal.by_id(sid).neutral_tick for sid, _ in pairs if sid in cal.ids}
    return pairs, neutral, None


def _chain_description(
    args: argparse.Namespace,
) -> tuple[list[tuple[int, str]], dict[int, int], str, str | None]:
    if args.model is not None and (args.head is not None or args.servos is not None):
        raise ValueError("--model goes with --ids (--servos and --head name each servo's model)")
    if args.head is not None:
        pairs, neutral, note = _head_chain(args.head)
        return pairs, neutral, f"head {args.head!r}", note
    if args.servos is not None:
        return args.servos, {}, "chain", None
    ids = args.ids if args.ids is not None else parse_ids("1-24")
    model = args.model or "XL330-M288"
    return [(sid, model) for sid in ids], {}, "chain", None


def _summary(pairs: list[tuple[int, str]]) -> str:
    groups: list[tuple[str, list[int]]] = []
    for sid, model in pairs:
        if groups and groups[-1][0] == model:
            groups[-1][1].append(sid)
        else:
            groups.append((model, [sid]))
    parts = [f"{len(ids)} x {model} ({'ids' if len(ids) > 1 else 'id'} {_ranges(ids)})" for model, ids in groups]
    return ", ".join(parts)


def _ranges(ids: list[int]) -> str:
    out: list[str] = []
    start = prev = ids[0]
    for sid in [*ids[1:], None]:
        if sid is not None and sid == prev + 1:
            prev = sid
            continue
        out.append(str(start) if start == prev else f"{start}-{prev}")
        if sid is not None:
            start = prev = sid
    return ",".join(out)


def _inject(chain: Any, faults: list[FaultSpec]) -> None:
    now = chain.time_s
    for f in faults:
        options: dict[str, Any] = {"start_s": now + f.start_s, "duration_s": f.duration_s, "replies": f.replies}
        if f.value is not None:
            options["delay_s" if f.kind == "late_reply" else "drop_bytes"] = (
                f.value if f.kind == "late_reply" else int(f.value)
            )
        chain.faults.inject(f.servo_id, f.kind, **options)


def run(args: argparse.Namespace) -> int:
    from servoface.calibration import CalibrationError
    from servoface.controller.cli.terminal import printable
    from servoface.controller.errors import ControllerError
    from servoface.hardware.emulator import FAULT_KINDS, EmulatorError, ServoChain
    from servoface.sim.errors import SimError

    try:
        pairs, neutral, what, note = _chain_description(args)
        for f in args.fault:
            parse_fault(f"{f.servo_id}:{f.kind}", FAULT_KINDS)  # the kind, checked against the emulator's list
        from servoface.hardware.emulator.chain import RUN_LOG_LIMIT

        chain = ServoChain.create(
            ids=pairs,
            log_limit=RUN_LOG_LIMIT,  # a long-running emulator: bounded memory
            baud=args.baud,
            wire_time=not args.no_wire_time,
            realism={"seed": args.seed} if args.realism else None,
        )
        for sid, tick in neutral.items():  # the head powers up at rest, as Face.open(emulate=True) does
            chain.servo(sid).move_by_hand(tick)
        _inject(chain, args.fault)
        on_signal_faults = [_parse_signal_fault(text) for text in args.fault_on_signal]
    except (ValueError, EmulatorError, SimError, ControllerError, CalibrationError, OSError) as err:
        print(f"servoface emulate: {printable(err)}", file=sys.stderr)
        return 2
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    def on_fault_signal(signum: int, frame: FrameType | None) -> None:
        for sid, kind, delay in on_signal_faults:
            chain.faults.inject_now(sid, kind, delay_s=delay)
        started = ", ".join(f"{kind} on servo {sid}" for sid, kind, _ in on_signal_faults) or "nothing"
        print(f"# fault-on-signal: {started} from now", file=sys.stderr, flush=True)  # a test waits for it

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
            extras = [" (no wire time)" if args.no_wire_time else "", " with realism" if args.realism else ""]
            faults = f"; {len(args.fault)} scripted fault(s)" if args.fault else ""
            print(
                f"# serving {what}: {_summary(pairs)} at {args.baud} bps{''.join(extras)}{faults}; "
                f"pty thread {chain.pty_priority}; Ctrl-C to stop",
                file=sys.stderr,
                flush=True,
            )
            if note is not None:
                print(f"# {note.replace('{pty}', path)}", file=sys.stderr, flush=True)
            while not stop.wait(0.2):
                pass
            if args.state_file is not None:
                write_state(chain, args.state_file)
            print(f"# pty: {chain.pty_stats}", file=sys.stderr, flush=True)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    return 0
