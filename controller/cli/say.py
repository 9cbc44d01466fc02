"""`servoface say "TEXT" --head NAME|PATH (--port P | --emulate) [--voice V] [--out DIR]`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from servoface.controller.cli.head_args import (
    add_head_arguments,
    check_expression,
    checked_calibration,
    open_errors,
    open_face,
)
from servoface.controller.cli.terminal import printable

HELP = "speak a text with lip sync on a head (espeak-ng); with --out, also write speech.wav, speech.toml, a video"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("text", help="what to say (plain text)")
    parser.add_argument("--voice", default="en-us", help="espeak-ng voice (default en-us)")
    parser.add_argument("--rate-wpm", type=int, default=None, help="speaking rate, words per minute (80..450)")
    parser.add_argument("--lead-ms", type=float, default=50.0, help="mouth ahead of the sound, ms (default 50)")
    parser.add_argument("--expression", default=None, help="hold this library expression while speaking")
    parser.add_argument("--out", type=Path, default=None, help="write speech.wav, speech.toml, speech.mp4 here")
    add_head_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from servoface.controller.au_names import head_au_names
    from servoface.controller.speech.errors import SpeechError
    from servoface.controller.speech.lipsync import speech_from_text
    from servoface.controller.speech.say import say_on_face, write_outputs
    from servoface.sim.heads import load_head

    # --rate and --lead-ms were range-checked by options.parse_command
    try:
        head = load_head(args.head)
        if args.expression:  # what to show first, as play: known and solved on the head
            check_expression(head, args.expression)
        calibration = checked_calibration(args, head)  # before espeak-ng runs and anything is written
        speech = speech_from_text(args.text, voice=args.voice, rate_wpm=args.rate_wpm, lead_s=args.lead_ms / 1e3)
        if args.out is not None:
            from servoface.controller.cli.outputs import writable_folder

            writable_folder(args.out)
            wav, script = write_outputs(speech, head.face_type, args.out, allowed=head_au_names(head))
            print(f"wrote {wav} and {script} (play it again: servoface play {script} --head {args.head} ...)")
        face = open_face(args, head, calibration)
    except (SpeechError, *open_errors()) as err:  # type: ignore[misc]  # mypy cannot read a starred tuple
        print(f"servoface say: {printable(err)}", file=sys.stderr)
        return 2
    with face:
        if args.expression:
            face.express(args.expression, hold_s=0.0)
        spoken = say_on_face(face, speech)
        perf = spoken.performance
        if args.out is not None:
            from servoface.controller.speech.video import plot_timing, render_talking

            plot = plot_timing(face, perf, speech, args.out / "speech_timing.png", latency_s=spoken.latency_s)
            print(f"wrote {plot}: the waveform against the jaw")
            video = args.out / "speech.mp4"
            count = render_talking(face, perf, speech, video)
            print(f"wrote {video}: {count} frames with sound ({speech.duration_s:.2f} s of speech)")
    s = perf.summary()
    print(f"{s['frames']} frames; verdicts {s['verdicts']}; {len(speech.plan.segments)} visemes")
    print(f"sound: {spoken.sound}; the mouth followed the {spoken.clock} clock")
    if spoken.budget is not None:
        b = spoken.budget
        print(
            f"jaw budget: account {b.account_before:.3f} -> {b.account_after:.3f} of {b.budget:.3f}; "
            f"thermal level {b.level}; jaw scaled down on {b.scaled_share:.0%} of the speech (min x{b.min_scale:.2f})"
        )
    return 130 if perf.interrupted else 0
