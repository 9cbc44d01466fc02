"""`servoface scan --port PORT [--baud B|all] [--ids 1-24]`: list the servos on a chain (id, model, fw)."""

from __future__ import annotations

import argparse
import sys

HELP = "find the servos on a port (a USB adapter, or the pty printed by `servoface emulate`)"
DYNAMIXEL_BAUDS = (57_600, 1_000_000, 115_200, 2_000_000, 3_000_000, 4_000_000, 9_600)  # likeliest first


def _baud(text: str) -> int | str:
    if text == "all":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--baud {text!r}: expected bits per second or 'all'") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", required=True, help="serial port, e.g. /dev/ttyUSB0, or a pty path")
    parser.add_argument(
        "--baud",
        type=_baud,
        default=1_000_000,
        help="baud rate (default 1000000), or 'all' to try every Dynamixel rate (factory default is 57600)",
    )
    parser.add_argument(
        "--ids",
        default=None,
        help="ids to ping, e.g. '1-24' or '1,3,7' (default: broadcast ping, ~2 s a baud; 4 s at 57600 if none answer)",
    )
    parser.add_argument(
        "--retries",
        type=int,
        default=2,
        help="ping a silent id (or repeat the broadcast ping) this many more times (default 2)",
    )
    parser.add_argument(
        "--latency-ms",
        type=float,
        default=None,
        help="SDK latency constant in ms (default: from the OS latency timer)",
    )


def run(args: argparse.Namespace) -> int:
    import warnings

    from servoface.controller.cli.exits import EXIT_USAGE
    from servoface.controller.cli.terminal import printable
    from servoface.hardware.bus import ids_from_spec, open_bus
    from servoface.hardware.errors import HardwareError
    from servoface.hardware.registers import HardwareErrorBits
    from servoface.hardware.scan import ScanResult, scan

    try:
        ids = ids_from_spec(args.ids) if args.ids else None
    except ValueError as err:
        print(f"servoface scan: --ids: {err}", file=sys.stderr)
        return 2
    # --retries, --latency-ms and --baud were range-checked by options.parse_command
    bauds = DYNAMIXEL_BAUDS if args.baud == "all" else (args.baud,)
    total = 0
    for i, baud in enumerate(bauds):
        if len(bauds) > 1:  # a few seconds a baud rate: say what is going on
            print(f"# trying {baud} bps ({i + 1} of {len(bauds)})", file=sys.stderr, flush=True)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                bus = open_bus("dynamixel", port=args.port, baud=baud, latency_timer_ms=args.latency_ms)
            except HardwareError as err:  # a port that does not exist or cannot be opened: the user's to fix
                print(f"servoface scan: {printable(err)}", file=sys.stderr)
                return EXIT_USAGE
        if i == 0:
            for warning in caught:
                print(f"warning: {warning.message}", file=sys.stderr)
        try:
            with bus:
                results: list[ScanResult] = scan(bus, ids, retries=args.retries)
        except HardwareError as err:
            print(f"servoface scan: {err}", file=sys.stderr)
            return 1
        total += len(results)
        if not results and len(bauds) > 1:
            continue
        how = f"ids {args.ids}" if ids else "broadcast ping"
        print(f"# {args.port} at {baud} bps, {how}: {len(results)} servo(s)")
        if not results:
            continue
        print(f"{'id':>4}  {'model':>6}  {'name':<14} {'firmware':>8}  hardware error")
        for r in results:
            if r.hardware_error is None:
                hw = "?"
            elif r.hardware_error == 0:
                hw = "none"
            else:
                hw = repr(HardwareErrorBits(r.hardware_error))
            print(f"{r.servo_id:>4}  {r.model_number:>6}  {r.model_name:<14} {r.firmware_version:>8}  {hw}")
    if not total and len(bauds) > 1:
        print(f"# {args.port}: no servo at any of {list(bauds)} bps")
        print(
            "# check the power supply and the wiring (data line, ground), and that nothing else has the "
            "port open; a servo on Protocol 1.0 does not answer Protocol 2.0 pings",
            file=sys.stderr,
        )
    elif not total:
        others = [b for b in DYNAMIXEL_BAUDS if b != args.baud]
        print(
            f"# no servo answered at {args.baud} bps; new servos ship at 57600 bps. Try "
            f"`servoface scan --port {args.port} --baud all` (tries {', '.join(map(str, others))})",
            file=sys.stderr,
        )
    return 0 if total else 1
