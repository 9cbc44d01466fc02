"""`servoface scan --port PORT [--baud B] [--ids 1-24]`: list the servos on a chain (id, model, firmware)."""

from __future__ import annotations

import argparse
import sys

HELP = "find the servos on a port (a USB adapter, or the pty printed by `servoface emulate`)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", required=True, help="serial port, e.g. /dev/ttyUSB0, or a pty path")
    parser.add_argument("--baud", type=int, default=1_000_000, help="baud rate (default 1000000)")
    parser.add_argument(
        "--ids",
        default=None,
        help="ids to ping, e.g. '1-24' or '1,3,7' (default: one broadcast ping, ~0.8 s)",
    )
    parser.add_argument(
        "--latency-ms",
        type=float,
        default=None,
        help="SDK latency constant in ms (default: from the OS latency timer)",
    )


def run(args: argparse.Namespace) -> int:
    import warnings

    from hardware.bus import ids_from_spec, open_bus
    from hardware.errors import HardwareError
    from hardware.registers import HardwareErrorBits
    from hardware.scan import scan

    try:
        ids = ids_from_spec(args.ids) if args.ids else None
    except ValueError as err:
        print(f"servoface scan: --ids: {err}", file=sys.stderr)
        return 2
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            bus = open_bus("dynamixel", port=args.port, baud=args.baud, latency_timer_ms=args.latency_ms)
        except HardwareError as err:
            print(f"servoface scan: {err}", file=sys.stderr)
            return 1
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    try:
        with bus:
            results = scan(bus, ids)
    except HardwareError as err:
        print(f"servoface scan: {err}", file=sys.stderr)
        return 1
    how = f"ids {args.ids}" if ids else "broadcast ping"
    print(f"# {args.port} at {args.baud} bps, {how}: {len(results)} servo(s)")
    print(f"{'id':>4}  {'model':>6}  {'name':<14} {'firmware':>8}  hardware error")
    for r in results:
        if r.hardware_error is None:
            hw = "?"
        elif r.hardware_error == 0:
            hw = "none"
        else:
            hw = repr(HardwareErrorBits(r.hardware_error))
        print(f"{r.servo_id:>4}  {r.model_number:>6}  {r.model_name:<14} {r.firmware_version:>8}  {hw}")
    return 0 if results else 1
