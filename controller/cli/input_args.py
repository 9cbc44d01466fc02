"""The input options `play --input`, `preview --input` and `stream` share (one definition, same names, same
meaning): frame rate and time unit of a file, shape ranges and a rest pose from the first seconds, tracker
confidence, which face to follow, gaze / head-pose switches, mirror. `read_options` turns them into the
readers' :class:`~servoface.controller.inputs.ReadOptions`."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from servoface.controller.inputs import ReadOptions, ShapeRanges


def add_input_arguments(parser: argparse.ArgumentParser, *, files: bool = True, fps_flag: str = "--fps") -> None:
    """The shared options; ``files=False`` (stream) leaves out the file-only ones (fps, time unit, bad rows,
    lost policy)."""
    group = parser.add_argument_group("input options", "how tracker data is read (README 'Inputs')")
    if files:
        group.add_argument(
            fps_flag,
            dest="input_fps",
            type=float,
            metavar="FPS",
            help="frame rate of a file without times (or with --time-unit frames); default: the reader's "
            "(py-feat 30, blendshapes 60, FAP its header)",
        )
        group.add_argument(
            "--time-unit",
            choices=("auto", "s", "ms", "us", "frames"),
            default="auto",
            help="unit of the file's time column (default auto: detected from the data and printed)",
        )
        group.add_argument(
            "--bad-rows",
            choices=("skip", "error"),
            default="skip",
            help="a row beyond the tolerances: skip it and count it (default) or stop with an error",
        )
        group.add_argument(
            "--lost",
            choices=("hold", "neutral"),
            default="hold",
            help="rows where tracking was lost: hold the last good AUs (default) or ease to neutral",
        )
    group.add_argument("--mirror", action="store_true", help="imitate a person facing the robot (swap L/R)")
    group.add_argument("--vergence", action="store_true", help="map eye-look differences to AU65/66")
    group.add_argument(
        "--min-confidence",
        type=float,
        default=None,
        help="ignore rows/messages below this tracker confidence 0..1 (default: OpenFace 0.8, py-feat 0.5, else 0)",
    )
    group.add_argument(
        "--face-id",
        type=int,
        default=None,
        help="which face to follow when the tracker saw several (OpenFace face_id; py-feat / MediaPipe: "
        "the K-th face from the left / in the result); default: one person, tracked",
    )
    group.add_argument(
        "--shape-ranges",
        type=Path,
        help="per-user blendshape rest/full ranges JSON (controller/inputs/shape_ranges.py)",
    )
    group.add_argument(
        "--rest-s",
        type=float,
        default=0.0,
        help="take the first S seconds as the user's rest pose (neutral face): scores and head angles are "
        "measured from it (default 0: off)",
    )
    group.add_argument("--no-gaze", action="store_true", help="do not move the eyes from the input (AU61-66)")
    group.add_argument("--no-head-pose", action="store_true", help="do not turn the head from the input (AU51-56)")


def load_shape_ranges(args: argparse.Namespace) -> ShapeRanges | None:
    if args.shape_ranges is None:
        return None
    from servoface.controller.inputs import ShapeRanges, load_blendshape_map

    return ShapeRanges.load(args.shape_ranges, load_blendshape_map().names)


def read_options(args: argparse.Namespace) -> ReadOptions:
    from servoface.controller.inputs import ReadOptions

    return ReadOptions(
        fps=getattr(args, "input_fps", None),
        time_unit=getattr(args, "time_unit", "auto"),
        min_confidence=args.min_confidence,
        face_id=args.face_id,
        gaze=not args.no_gaze,
        head_pose=not args.no_head_pose,
        mirror=args.mirror,
        rest_s=args.rest_s,
        shape_ranges=load_shape_ranges(args),
        lost=getattr(args, "lost", "hold"),
        bad_rows=getattr(args, "bad_rows", "skip"),
        vergence=args.vergence,
    )
