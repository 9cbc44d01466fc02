"""`servoface say` and `servoface lipsync` end to end (real synthesis, real alignment, real rendering), and
the script they write plays with `servoface play` and round-trips the plan."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from servoface.controller.script import load_script
from servoface.controller.speech.lipsync import speech_from_text

ENV = {**os.environ, "PYOPENGL_PLATFORM": "egl"}


def _servoface(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "servoface.controller.cli", *args],
        cwd=cwd,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
    )


def _streams(path: Path) -> str:
    import imageio_ffmpeg

    proc = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-i", str(path)], capture_output=True, text=True)
    return proc.stderr


def test_script_round_trips_the_plan(tmp_path: Path) -> None:
    from servoface.controller.speech.say import write_outputs

    speech = speech_from_text("Peter picked a peck of pickled peppers.")
    wav, script_path = write_outputs(speech, "human", tmp_path)
    script = load_script(script_path)
    assert script.audio_path == wav and script.audio_start_s == pytest.approx(speech.plan.audio_start_s)
    clip = speech.plan.clip("human")
    for t in np.arange(0.0, speech.plan.duration_s, 0.037):
        expect = clip.sample(float(t), {})
        got = script.sample(float(t)).aus
        for au, value in expect.items():
            assert got.get(au, 0.0) == pytest.approx(value, abs=2e-3), (au, t)


@pytest.mark.slow
def test_say_writes_audio_script_and_a_video_with_sound(tmp_path: Path) -> None:
    proc = _servoface("say", "Hello, I am a robot.", "--emulate", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "out"
    assert {p.name for p in out.iterdir()} >= {"speech.wav", "speech.toml", "speech.mp4"}
    streams = _streams(out / "speech.mp4")
    assert "Video: h264" in streams and "Audio: aac" in streams
    again = _servoface("play", str(out / "speech.toml"), "--emulate", cwd=tmp_path)
    assert again.returncode == 0, again.stderr


@pytest.mark.slow
def test_lipsync_of_a_recording_with_and_without_its_text(tmp_path: Path) -> None:
    speech = speech_from_text("Bob bought a big blue balloon.")
    from servoface.controller.speech.audio import write_wav

    wav = write_wav(tmp_path / "take.wav", (speech.samples * 32767).astype(np.int16), speech.rate_hz)
    aligned = _servoface(
        "lipsync",
        str(wav),
        "--text",
        "Bob bought a big blue balloon.",
        "--head",
        "dog",
        "--out",
        "aligned",
        cwd=tmp_path,
    )
    assert aligned.returncode == 0, aligned.stderr
    assert aligned.stdout.startswith("aligned:") and "warning" not in aligned.stderr, aligned.stderr
    assert "Audio: aac" in _streams(tmp_path / "aligned" / "speech.mp4")
    envelope = _servoface("lipsync", str(wav), "--out", "env", "--no-video", cwd=tmp_path)
    assert envelope.returncode == 0 and envelope.stdout.startswith("envelope:"), envelope.stderr
    assert load_script(tmp_path / "env" / "speech.toml").end_s > 1.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["lipsync", "missing.wav"], "cannot read"),
        (["lipsync", "notes.txt"], "cannot read"),
        (
            ["lipsync", "notes.txt", "--transcript", "the birch canoe"],
            "--transcript 'the birch canoe': no such file; the transcript's words themselves go in --text",
        ),
        (["lipsync", "notes.txt", "--transcript", "binary.txt"], "--transcript 'binary.txt': not UTF-8 text"),
        (["say", "", "--emulate"], "text"),
        (["say", "hi", "--voice", "zz-nope", "--emulate"], "voice"),
        (["say", "hi", "--lead-ms", "-5", "--emulate"], "lead-ms"),
    ],
)
def test_bad_input_is_a_message_not_a_traceback(tmp_path: Path, args: list[str], message: str) -> None:
    (tmp_path / "notes.txt").write_text("not audio")
    (tmp_path / "binary.txt").write_bytes(b"\xff\xfe\x00\x81 not text")
    proc = _servoface(*args, cwd=tmp_path)
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
