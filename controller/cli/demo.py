"""`servoface demo [--out DIR] [--head human|dog|PATH] [--show achievable|target|both]`: a head on the
emulated chain, end to end (a profile folder plays its expression library)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "play a head's performance on the emulated chain; write twin video, contact sheet, report.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default out/demo)")
    parser.add_argument("--head", default="human", help="built-in head (human, dog; default human) or a profile folder")
    parser.add_argument(
        "--show",
        choices=["achievable", "target", "both"],
        default="achievable",
        help="what the video and sheet draw: the face the servos make (default), the muscle target, or both",
    )
    parser.add_argument("--format", choices=["mp4", "gif"], default="mp4", help="twin video format (default mp4)")
    parser.add_argument("--baud", type=int, default=1_000_000, help="emulated bus speed (default 1000000)")
    parser.add_argument("--rate", type=float, default=50.0, help="control rate in Hz (default 50)")


def run(args: argparse.Namespace) -> int:
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from servoface.controller.cli import describe_os_error
    from servoface.controller.cli.exits import EXIT_USAGE, exit_code, head_hint, head_message
    from servoface.controller.cli.outputs import writable_folder
    from servoface.controller.cli.terminal import printable
    from servoface.controller.demo import run_demo

    head = args.head
    from servoface.calibration import CalibrationError
    from servoface.controller.errors import ControllerError
    from servoface.hardware.errors import HardwareError
    from servoface.sim.errors import SimError
    from servoface.sim.heads import load_head

    try:  # the head checked before anything is opened or announced
        load_head(head)
    except (SimError, OSError) as err:
        print(f"servoface demo: {printable(head_message(head, err))}", file=sys.stderr)
        print(f"  {head_hint(head)}", file=sys.stderr)
        return EXIT_USAGE
    try:
        writable_folder(args.out)
    except OSError as err:
        print(f"servoface demo: --out {args.out}: {describe_os_error(err)}", file=sys.stderr)
        return exit_code(err)
    try:
        out = run_demo(
            args.out,
            head=head,
            video_format=args.format,
            baud=args.baud,
            rate_hz=args.rate,
            progress=lambda msg: print(f"servoface demo: {msg}", file=sys.stderr, flush=True),
            show=args.show,
        )
    except (SimError, CalibrationError, ControllerError, HardwareError) as err:
        print(f"servoface demo: {printable(head_message(head, err))}", file=sys.stderr)
        print(f"  next: `servoface check {head}` names what to fix", file=sys.stderr)
        return exit_code(err)
    r = out.report_data
    loop = r["loop"]
    print(
        f"head {head}: {r['frames']} frames, verdicts {r['verdicts']}, "
        f"loop {loop['achieved_hz']} Hz of {loop['target_hz']:g} Hz target, late {loop['late_frames']}, "
        f"max goal error after settling {r['max_goal_error_tick']} tick"
    )
    print(f"  video  {out.video}")
    print(f"  sheet  {out.sheet}")
    if out.clipped_frame is not None:
        print(f"  clip   {out.clipped_frame}")
    print(f"  report {out.report}")
    return 0
