"""`servoface lipsync AUDIO.wav [--text T | --transcript FILE] --head NAME|PATH [--out DIR]`.

With a transcript, the transcript check's doubts (``speech/align_check.py``) are printed as a warning on
stderr and the lip sync goes ahead; a gross mismatch is an error (exit 2) unless ``--allow-mismatch``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "lip sync for recorded speech: a timeline script (speech.toml) and a twin video with the sound"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("audio", type=Path, help="a PCM WAV file (any rate, mono or stereo)")
    what = parser.add_mutually_exclusive_group()
    what.add_argument("--text", help="its transcript: forced alignment (pocketsphinx, English)")
    what.add_argument("--transcript", type=Path, help="a text file with its transcript")
    parser.add_argument("--head", default="human", help="built-in head (human, dog) or a profile folder")
    parser.add_argument("--out", type=Path, default=Path("out/lipsync"), help="output folder (default out/lipsync)")
    parser.add_argument("--lead-ms", type=float, default=50.0, help="mouth ahead of the sound, ms (default 50)")
    parser.add_argument("--no-video", action="store_true", help="write only the script and the audio")
    parser.add_argument(
        "--allow-mismatch",
        action="store_true",
        help="lip-sync even when the transcript does not seem to be the text of the audio (a warning then)",
    )


def run(args: argparse.Namespace) -> int:
    from servoface.controller.au_names import head_au_names
    from servoface.controller.cli.head_args import checked_calibration, open_errors
    from servoface.controller.cli.terminal import printable
    from servoface.controller.speech.audio import read_wav
    from servoface.controller.speech.errors import SpeechError, TranscriptMismatchError
    from servoface.controller.speech.lipsync import speech_from_recording
    from servoface.controller.speech.say import say_on_face, write_outputs
    from servoface.sim.heads import load_head

    # Every input is read and checked before --out is made, so a refused run leaves no folder behind; --out
    # itself is checked (not made) before the alignment, and made only once the lip sync is done.
    # --lead-ms was range-checked by options.parse_command.
    try:
        head = load_head(args.head)
        transcript = args.text
        if args.transcript is not None:
            transcript = _read_transcript(args.transcript)
        recording = read_wav(args.audio)
        # the video plays the head on its emulated servos: its calibration must be usable (else exit 2 with
        # nothing written, not after the lip sync's files)
        calibration = None if args.no_video else checked_calibration(args, head)
        _check_out_folder(args.out)
        speech = speech_from_recording(
            recording, transcript, lead_s=args.lead_ms / 1e3, allow_mismatch=args.allow_mismatch
        )
        _make_out_folder(args.out)
        wav, script = write_outputs(speech, head.face_type, args.out, allowed=head_au_names(head))
    except (TranscriptFileError, OutFolderError) as err:
        print(f"servoface lipsync: {printable(err)}", file=sys.stderr)
        return 2
    except TranscriptMismatchError as err:
        print(f"servoface lipsync: {printable(err)} (--allow-mismatch lip-syncs anyway)", file=sys.stderr)
        return 2
    except (SpeechError, *open_errors()) as err:  # type: ignore[misc]  # mypy cannot read a starred tuple
        print(f"servoface lipsync: {printable(err)}", file=sys.stderr)
        return 2
    check = speech.transcript_check
    if check is not None and not check.ok:
        print(f"servoface lipsync: warning: {printable(check.message())}", file=sys.stderr)
    print(f"{speech.method}: {len(speech.plan.segments) or 'envelope'} visemes over {speech.duration_s:.2f} s")
    print(printable(f"wrote {script} (servoface play {script} --head {args.head} --emulate) and {wav}"))
    if args.no_video:
        return 0
    from servoface.controller.face import Face
    from servoface.controller.speech.video import render_talking
    from servoface.sim.errors import RenderError

    video = args.out / "speech.mp4"
    try:
        with Face.open(head, emulate=True, calibration=calibration) as face:
            perf = say_on_face(face, speech, audio_out=False).performance
            count = render_talking(face, perf, speech, video)
    except RenderError as err:  # rendering unavailable or failed: the run failed (1), its other files stand
        print(f"servoface lipsync: {printable(err)} (the script and sound above are written)", file=sys.stderr)
        return 1
    print(f"wrote {printable(video)}: {count} frames, the achievable face with the sound")
    return 0


class TranscriptFileError(Exception):
    """``--transcript FILE`` cannot be read as text (the message names the flag, the path and what to do)."""


def _read_transcript(path: Path) -> str:
    """The text of ``--transcript FILE``; a path that is not there but reads like words is pointed at --text."""
    from servoface.controller.cli import describe_os_error
    from servoface.sim.textfile import read_bounded

    def refuse(reason: str) -> TranscriptFileError:
        return TranscriptFileError(f"--transcript {str(path)!r}: {reason}")

    try:  # a stream is welcome (`--transcript <(...)`), up to the limit: /dev/zero is refused, not read for ever
        return read_bounded(path, refuse, what="a transcript", allow_stream=True).decode("utf-8")
    except UnicodeDecodeError as err:
        why = f"{err.reason} at byte {err.start}"
        raise TranscriptFileError(f"--transcript {str(path)!r}: not UTF-8 text ({why})") from err
    except FileNotFoundError as err:
        hint = 'the transcript\'s words themselves go in --text "..."' if " " in str(path) else "check the path"
        raise TranscriptFileError(f"--transcript {str(path)!r}: no such file; {hint}") from err
    except OSError as err:
        raise TranscriptFileError(f"--transcript {str(path)!r}: {describe_os_error(err)}") from err


class OutFolderError(Exception):
    """``--out DIR`` cannot be made or written (the message names the flag, the path and what to do)."""


def _check_out_folder(folder: Path) -> None:
    """Refuse ``--out`` if it could not be made or written, without making it (`outputs.folder_could_be_made`)."""
    from servoface.controller.cli import outputs

    try:
        outputs.folder_could_be_made(folder)
    except NotADirectoryError as err:
        raise OutFolderError(f"--out {str(folder)!r}: {err.strerror}") from err
    except PermissionError as err:
        raise OutFolderError(f"--out {str(folder)!r}: {err.strerror}; choose another folder") from err


def _make_out_folder(folder: Path) -> None:
    """Make ``--out`` (`outputs.writable_folder`), a failure worded as OutFolderError."""
    from servoface.controller.cli import describe_os_error, outputs

    try:
        outputs.writable_folder(folder)
    except OSError as err:
        why = describe_os_error(err).removeprefix(f"cannot use {str(folder)!r}: ")
        raise OutFolderError(f"--out {str(folder)!r}: {why}") from err
