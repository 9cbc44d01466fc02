"""`servoface preview`: render an expression (still at its apex, or a GIF/MP4 clip) or the whole library."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "render an expression of a head to PNG (apex), GIF/MP4 (neutral -> apex -> neutral), or --all as a sheet"
STILL = (".png", ".jpg", ".jpeg")
CLIP = (".gif", ".mp4")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("expression", nargs="?", metavar="EXPR", help="expression name from the head's library")
    parser.add_argument("--all", action="store_true", help="every expression of the library on one sheet")
    parser.add_argument("--head", default="human", help="built-in head (human, dog) or a profile folder")
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        type=Path,
        help="output file: .png/.jpg (still or sheet), .gif/.mp4 (clip)",
    )
    parser.add_argument(
        "--size",
        default=None,
        help="WIDTHxHEIGHT in pixels (default 640x480; per cell with --all, default 320x240)",
    )
    parser.add_argument(
        "--view",
        default=None,
        choices=["front", "three-quarter", "side"],
        help="camera (default: front for a human head, three-quarter for a dog)",
    )
    parser.add_argument(
        "--input",
        type=Path,
        help="instead of EXPR: a recorded tracker file (as `play --input`): a still of its most expressive "
        "frame (or --at S), or a clip of it",
    )
    parser.add_argument("--at", type=float, default=None, help="with --input and a still: the time to show (s)")
    parser.add_argument(
        "--duration", type=float, default=None, help="clip length in seconds (default 2.0; --input: its length)"
    )
    parser.add_argument("--fps", type=float, default=20.0, help="clip frame rate (default 20)")
    parser.add_argument("--columns", type=int, default=None, help="sheet columns with --all (default: about square)")
    parser.add_argument(
        "--show",
        choices=["achievable", "target", "both"],
        default="achievable",
        help="achievable (default): the face the servos make (gated command posed by the twin); "
        "target: the muscle model's wish; both: side by side",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    from servoface.controller.cli.input_args import add_input_arguments

    add_input_arguments(parser, fps_flag="--input-fps")


def _fail(message: str, code: int = 2) -> int:
    print(f"servoface preview: {message}", file=sys.stderr)
    return code


def run(args: argparse.Namespace) -> int:
    # cheap checks first: nothing heavy is imported and nothing is written on bad input
    if args.all + (args.expression is not None) + (args.input is not None) != 1:
        return _fail("give one expression name, or --all for the whole library, or --input FILE")
    if args.at is not None and args.input is None:
        return _fail("--at picks a moment of a recording: it goes with --input FILE (an expression shows its apex)")
    suffix = args.output.suffix.lower()
    allowed = STILL if args.all else STILL + CLIP
    if suffix not in allowed:
        what = "a sheet" if args.all else "a preview"
        return _fail(f"output {args.output}: {what} must end in {', '.join(allowed)}, got {suffix or 'no extension'!r}")
    if not args.output.parent.exists():
        return _fail(f"output {args.output}: folder {args.output.parent} does not exist")
    from servoface.controller.cli.outputs import writable_file

    try:
        writable_file(args.output)
    except OSError as err:
        from servoface.controller.cli import describe_os_error

        return _fail(f"output {args.output}: {describe_os_error(err)}")

    from servoface.calibration import CalibrationError
    from servoface.controller.errors import ControllerError
    from servoface.sim.errors import ExpressionError, HeadProfileError, RenderError, SimError
    from servoface.sim.render.renderer import parse_size

    try:
        width, height = parse_size(args.size or ("320x240" if args.all else "640x480"))
    except ValueError as err:
        return _fail(f"--size: {err}")
    if suffix in CLIP:
        from servoface.sim.render.video import there_and_back

        try:
            there_and_back(2.0 if args.duration is None else args.duration, args.fps)
        except ValueError as err:
            return _fail(str(err))

    from servoface.sim.expressions import load_library
    from servoface.sim.heads import load_head
    from servoface.sim.render.camera import default_view
    from servoface.sim.render.clips import clip_frames, library_sheet, pick_expression, render_aus
    from servoface.sim.render.images import save_image
    from servoface.sim.render.renderer import HeadRenderer
    from servoface.sim.render.video import WRITERS

    try:
        head = load_head(args.head)
    except (HeadProfileError, FileNotFoundError, KeyError, ValueError) as err:
        from servoface.controller.cli.exits import head_hint, head_message

        return _fail(f"{head_message(args.head, err)}\n  {head_hint(args.head)}")
    if args.input is not None:
        from servoface.controller.cli.preview_input import preview_input

        return preview_input(args, head, (width, height), suffix in CLIP)
    try:
        library = load_library(head.expressions_path or head.face_type)  # a profile may bring its own
        aus = None if args.all else pick_expression(library, args.expression)
    except ExpressionError as err:
        return _fail(str(err))
    try:  # the head's AU table, direct table and muscles take every expression shown: before any render
        from servoface.controller.cli.head_args import check_on_head
        from servoface.sim.render.twin import face_model

        names = [*library] if args.all else [args.expression]
        check_on_head(head, library, names, model=face_model(head))  # (the model the renders reuse)
    except SimError as err:
        from servoface.controller.cli.exits import exit_code

        return _fail(f"{err}\n  next: `servoface check {args.head}` names what to fix", code=exit_code(err))

    bar = False if args.quiet else None
    view = args.view or default_view(head.face_type)
    twin = None
    if args.show != "target":
        from servoface.sim.achievable import AchievableFace

        try:
            twin = AchievableFace(head, frame_period_s=1.0 / args.fps if suffix in CLIP else 0.02)
        except (SimError, CalibrationError) as err:  # a broken profile or calibration file: bad input
            from servoface.controller.cli.exits import exit_code

            return _fail(f"{err}\n  next: `servoface check {args.head}` names what to fix", code=exit_code(err))
        if twin.note:
            print(f"servoface preview: note: {twin.note}", file=sys.stderr)
    shown_as = {"achievable": "what the servos make", "target": "muscle-model target", "both": "target | servos"}
    try:
        with HeadRenderer(width, height, view=view) as renderer:
            if args.all:
                sheet, names = library_sheet(
                    renderer, head, library, args.columns, show_progress=bar, show=args.show, achievable=twin
                )
                save_image(sheet, args.output)
                print(
                    f"wrote {args.output}: {len(names)} expressions of {head.name!r} ({shown_as[args.show]}): "
                    f"{', '.join(names)}"
                )
            elif suffix in CLIP:
                duration_s = 2.0 if args.duration is None else args.duration
                frames = clip_frames(
                    renderer, head, aus or {}, duration_s, args.fps, show_progress=bar, show=args.show,
                    achievable=twin,
                )  # fmt: skip
                count = WRITERS[suffix](frames, args.output, args.fps)
                print(
                    f"wrote {args.output}: {count} frames at {args.fps:g} fps "
                    f"({args.expression}, {shown_as[args.show]})"
                )
            else:
                save_image(render_aus(renderer, head, aus or {}, show=args.show, achievable=twin), args.output)
                print(
                    f"wrote {args.output}: {args.expression} at apex on {head.name} ({width}x{height}, "
                    f"{shown_as[args.show]})"
                )
                if twin is not None:
                    _say_gap(twin, aus or {})
    except RenderError as err:  # rendering unavailable or failed: the run failed (1)
        return _fail(str(err), code=1)
    except (SimError, CalibrationError, ControllerError) as err:  # the profile, calibration or library: 2
        from servoface.controller.cli.exits import exit_code

        return _fail(f"{err}\n  next: `servoface check {args.head}` names what to fix", code=exit_code(err))
    return 0


def _say_gap(twin: object, aus: dict[str, float]) -> None:
    """One line on how far the servos fall short of the muscle model's targets (the honest part)."""
    got = twin.still(aus)  # type: ignore[attr-defined]
    gaps = sorted(((abs(got.wanted[r] - got.targets[r]), r) for r in got.targets), reverse=True)
    short = [f"{r} {got.targets[r]:.1f} of {got.wanted[r]:.1f}" for g, r in gaps if g > 0.5][:4]
    if short:
        print(f"  the servos fall short of the muscle model: {', '.join(short)} (deg/mm); --show both compares")
    if got.verdict not in ("accept", "ranges"):
        print(f"  twin gate: {got.verdict}: {'; '.join(got.reasons[:2])}")
