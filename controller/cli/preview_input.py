"""`servoface preview --input FILE -o out.png|gif|mp4`: render a recorded tracker file on a head (as
`preview EXPR`: the face the servos make by default, ``--show target|both``), after printing what the
reader made of the file (the same summary as `play --input`). A still shows the most expressive frame
(largest sum of AU intensities) or the one at ``--at S``; a clip samples the recording at ``--fps`` over
its length (or ``--duration``)."""

from __future__ import annotations

import argparse
import sys
from typing import Any


def preview_input(args: argparse.Namespace, head: Any, size: tuple[int, int], clip: bool) -> int:
    from servoface.calibration import CalibrationError
    from servoface.controller.cli.input_args import read_options
    from servoface.controller.errors import ControllerError
    from servoface.controller.inputs import HeadRanges, fit_recording, load_recording
    from servoface.sim.achievable import AchievableFace
    from servoface.sim.errors import RenderError, SimError
    from servoface.sim.render.camera import default_view
    from servoface.sim.render.clips import render_aus, render_sequence
    from servoface.sim.render.images import save_image
    from servoface.sim.render.progress import progress
    from servoface.sim.render.renderer import HeadRenderer
    from servoface.sim.render.twin import face_model
    from servoface.sim.render.video import WRITERS

    try:
        recording = load_recording(args.input, head.face_type, options=read_options(args))
        recording = fit_recording(recording, HeadRanges.of(head))  # as `play --input` plays it
    except ControllerError as err:
        print(f"servoface preview: {err}", file=sys.stderr)
        return 2
    print("\n".join(recording.report.lines()))
    width, height = size
    view = args.view or default_view(head.face_type)
    shown = getattr(args, "show", "achievable")
    try:  # the head's face model (AU and direct tables, muscles) and its calibration, before any render
        face_model(head)
        twin = None if shown == "target" else AchievableFace(head, frame_period_s=1.0 / args.fps if clip else 0.02)
    except (SimError, CalibrationError) as err:  # a profile or calibration that does not fit the head: say so
        from servoface.controller.cli.exits import exit_code

        print(f"servoface preview: {err}\n  next: `servoface check {args.head}` names what to fix", file=sys.stderr)
        return exit_code(err)
    try:
        with HeadRenderer(width, height, view=view) as renderer:
            if clip:
                length_s = recording.duration_s if args.duration is None else args.duration
                count = max(1, int(length_s * args.fps) + 1)
                times = [k / args.fps for k in range(count)]
                show = False if args.quiet else None
                frames = render_sequence(
                    renderer,
                    head,
                    (recording.sample(t).aus for t in progress(times, total=count, desc="frames", enabled=show)),
                    show=shown,
                    achievable=twin,
                )
                written = WRITERS[args.output.suffix.lower()](frames, args.output, args.fps)
                print(f"wrote {args.output}: {written} frames at {args.fps:g} fps of {args.input}")
            else:
                if args.at is not None:
                    frame = recording.sample(args.at)
                    what = f"at {args.at:g} s"
                else:
                    frame = max(recording.frames, key=lambda f: sum(abs(v) for v in f.aus.values()))
                    what = f"its most expressive frame, at {frame.t_s:.3f} s"
                save_image(render_aus(renderer, head, frame.aus, show=shown, achievable=twin), args.output)
                print(f"wrote {args.output}: {args.input} {what} on {head.name} ({width}x{height})")
    except RenderError as err:  # rendering unavailable or failed: the run failed (1)
        print(f"servoface preview: {err}", file=sys.stderr)
        return 1
    except (SimError, CalibrationError, ControllerError) as err:  # the profile or the recording: bad input (2)
        from servoface.controller.cli.exits import exit_code

        print(f"servoface preview: {err}\n  next: `servoface check {args.head}` names what to fix", file=sys.stderr)
        return exit_code(err)
    return 0
