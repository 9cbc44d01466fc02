"""`servoface lipsync AUDIO --out DIR` reads and checks every input (head, transcript, the WAV) before it
makes DIR: a refused run exits 2 with one line naming what was wrong and leaves no folder behind. An --out
that cannot be made or written is refused with its own line, before the alignment."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from servoface.controller.cli import main
from servoface.controller.speech.audio import write_wav

POSIX = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs are POSIX only")


def _take(folder: Path, name: str = "take.wav") -> Path:
    """One second of noise as a 16-bit WAV (the envelope lip sync needs no words)."""
    rng = np.random.default_rng(7)
    return write_wav(folder / name, (rng.uniform(-0.3, 0.3, 16_000) * 32767).astype(np.int16), 16_000)


def _refused(status: int, out: str, err: str, *expected: str) -> str:
    """The one line of a refusal (exit 2, nothing on stdout, no traceback) that says each of ``expected``."""
    assert status == 2, out + err
    assert out == "", out
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("servoface lipsync: "), err
    for part in expected:
        assert part in lines[0], lines[0]
    return lines[0]


def _bad_input(kind: str, folder: Path) -> tuple[list[str], tuple[str, ...]]:
    """The lipsync arguments (before --out) of one kind of bad input, and what its refusal must say."""
    if kind == "missing_wav":
        wav = folder / "missing.wav"
        return [str(wav)], (str(wav), "cannot read as a PCM WAV file")
    if kind == "not_a_wav":
        (folder / "notes.wav").write_text("not audio")
        return [str(folder / "notes.wav")], ("notes.wav: cannot read as a PCM WAV file (file does not start",)
    if kind == "fifo":
        os.mkfifo(folder / "take.wav")
        return [str(folder / "take.wav")], ("take.wav: a pipe (FIFO), not a regular file; expected a WAV file",)
    if kind == "too_big":
        with (folder / "huge.wav").open("wb") as fh:  # sparse: 2.1 GiB declared, no blocks written
            fh.truncate(2_254_857_830)
        return [str(folder / "huge.wav")], ("huge.wav: 2.1 GiB; a WAV file is at most 512 MiB",)
    if kind == "directory":
        (folder / "takes.wav").mkdir()
        return [str(folder / "takes.wav")], ("takes.wav: a directory, not a regular file",)
    wav = str(_take(folder))
    if kind == "missing_transcript":
        return [wav, "--transcript", str(folder / "words.txt")], ("--transcript", "words.txt", "no such file")
    if kind == "binary_transcript":
        (folder / "words.txt").write_bytes(b"\xff\xfe\x00\x81 not text")
        return [wav, "--transcript", str(folder / "words.txt")], ("--transcript", "not UTF-8 text")
    if kind == "head":
        return [wav, "--head", "hman"], ("hman: expected a built-in head name", "did you mean 'human'?")
    assert kind == "lead", kind
    return [wav, "--lead-ms", "-5"], ("--lead-ms",)


KINDS = [
    "missing_wav",
    "not_a_wav",
    pytest.param("fifo", marks=POSIX),
    "too_big",
    "directory",
    "missing_transcript",
    "binary_transcript",
    "head",
    "lead",
]


@pytest.mark.parametrize("kind", KINDS)
def test_bad_input_leaves_no_output_folder(kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args, expected = _bad_input(kind, tmp_path)
    out_dir = tmp_path / "new" / "lipsync"  # neither it nor its parent exists
    status = main(["lipsync", *args, "--out", str(out_dir), "--no-video"])
    out, err = capsys.readouterr()
    _refused(status, out, err, *expected)
    assert not (tmp_path / "new").exists(), sorted(p.name for p in tmp_path.iterdir())


@POSIX
def test_a_fifo_recording_through_the_command_leaves_no_folder(tmp_path: Path) -> None:
    """The installed command end to end: exit 2, the one line, no `out` folder (and no hang on the FIFO)."""
    os.mkfifo(tmp_path / "take.wav")
    proc = subprocess.run(
        [sys.executable, "-m", "servoface.controller.cli", "lipsync", "take.wav", "--out", "out"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYOPENGL_PLATFORM": "egl"},
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == "servoface lipsync: take.wav: a pipe (FIFO), not a regular file; expected a WAV file\n"
    assert proc.stdout == ""
    assert not (tmp_path / "out").exists()


def test_a_transcript_that_is_not_the_audio_leaves_no_output_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A gross mismatch is found by the alignment, after the inputs are read: still exit 2 and no folder."""
    from servoface.controller.speech.audio import to_float
    from servoface.controller.speech.espeak import synthesize

    speech = synthesize("Bob bought a big blue balloon for the baby.")
    wav = write_wav(tmp_path / "take.wav", (to_float(speech.samples) * 32767).astype(np.int16), speech.sample_rate_hz)
    out_dir = tmp_path / "out"
    status = main(["lipsync", str(wav), "--text", "The juice of lemons makes fine punch.", "--out", str(out_dir)])
    out, err = capsys.readouterr()
    _refused(status, out, err, "--allow-mismatch lip-syncs anyway")
    assert not out_dir.exists()


def test_a_good_recording_makes_the_nested_output_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "new" / "lipsync"
    status = main(["lipsync", str(_take(tmp_path)), "--out", str(out_dir), "--no-video"])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    assert out.startswith("envelope:") and (out_dir / "speech.toml").exists() and (out_dir / "speech.wav").exists()


@pytest.mark.parametrize("where", ["is_a_file", "under_a_file"])
def test_an_out_path_through_a_file_has_its_own_message(
    where: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    wav = _take(tmp_path)
    blocker = tmp_path / "notes.txt"
    blocker.write_text("in the way")
    out_dir = blocker if where == "is_a_file" else blocker / "lipsync"
    status = main(["lipsync", str(wav), "--out", str(out_dir), "--no-video"])
    out, err = capsys.readouterr()
    what = "not a folder" if where == "is_a_file" else f"{str(blocker)!r} is not a folder"
    _refused(status, out, err, f"--out {str(out_dir)!r}: {what}; expected an output folder")
    assert blocker.read_text() == "in the way"


def test_an_out_folder_without_write_permission_is_refused_before_the_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """As a user without write permission on the parent sees it (the test may run as root, for whom every
    folder is writable: the permission answer is the operating system's, stood in for here)."""
    from servoface.controller.speech import lipsync

    wav = _take(tmp_path)
    parent = tmp_path / "locked"
    parent.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == parent else real_access(p, mode))

    def no_work(*args: object, **kwargs: object) -> None:
        raise AssertionError("the lip sync ran for an output folder that cannot be written")

    monkeypatch.setattr(lipsync, "speech_from_recording", no_work)
    status = main(["lipsync", str(wav), "--out", str(parent / "lipsync"), "--no-video"])
    out, err = capsys.readouterr()
    _refused(status, out, err, f"--out {str(parent / 'lipsync')!r}", f"cannot write in {str(parent)!r}")
    assert list(parent.iterdir()) == []


def test_an_out_folder_that_cannot_be_made_after_all_has_its_own_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The check before the work passed but making the folder failed (a disk that went read-only)."""
    import errno

    from servoface.controller.cli import outputs

    def read_only(folder: Path) -> Path:
        raise OSError(errno.EROFS, "Read-only file system (cannot write in this folder)", str(folder))

    monkeypatch.setattr(outputs, "writable_folder", read_only)
    out_dir = tmp_path / "lipsync"
    status = main(["lipsync", str(_take(tmp_path)), "--out", str(out_dir), "--no-video"])
    out, err = capsys.readouterr()
    line = _refused(status, out, err, f"--out {str(out_dir)!r}: Read-only file system", "writable file system")
    assert line.count(str(out_dir)) == 1, line  # the folder named once


def test_the_message_shows_escape_sequences_escaped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    wav = tmp_path / "take\x1b[31m.wav"
    status = main(["lipsync", str(wav), "--out", str(tmp_path / "out"), "--no-video"])
    out, err = capsys.readouterr()
    line = _refused(status, out, err, "take\\x1b[31m.wav")
    assert "\x1b" not in line


def test_a_head_without_a_calibration_is_refused_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The video plays the head on its emulated servos: a head that has no calibration yet is refused (exit 2,
    one line naming what to run) before the lip sync writes its script and sound; with --no-video it does not
    matter and the files are written."""
    import shutil

    head = tmp_path / "uncal"
    shutil.copytree(Path(__file__).resolve().parents[2] / "sim" / "heads" / "human", head)
    (head / "calibration.json").unlink()
    take, out = _take(tmp_path), tmp_path / "made" / "lipsync"
    status = main(["lipsync", str(take), "--text", "hello", "--head", str(head), "--out", str(out)])
    got, err = capsys.readouterr()
    assert status == 2, got + err
    assert "no calibration file" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "made").exists()
    status = main(["lipsync", str(take), "--text", "hello", "--head", str(head), "--out", str(out), "--no-video"])
    got, err = capsys.readouterr()
    assert status == 0, got + err
    assert (out / "speech.wav").is_file() and not (out / "speech.mp4").exists()
