"""`read_wav` (controller/speech/audio.py) reads bounded: a FIFO, a device or a directory is refused before it
is opened, a file over AUDIO_LIMIT_BYTES before it is read; a real WAV reads as it always did."""

from __future__ import annotations

import os
import subprocess
import sys
import wave
from pathlib import Path

import numpy as np
import pytest
from servoface.calibration import boundedfile
from servoface.controller.speech import audio
from servoface.controller.speech.audio import read_wav, write_wav
from servoface.controller.speech.errors import SpeechError

from tests.fifo import settle

POSIX = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs need a POSIX system")


def _pcm(path: Path, frames: np.ndarray, width: int, rate_hz: int = 16000) -> Path:
    """A PCM WAV of ``frames`` ((n, channels) ints in the sample width's range) written by the stdlib."""
    if width == 1:
        raw = (frames + 128).astype(np.uint8).tobytes()
    elif width == 3:
        raw = frames.astype("<i4").view(np.uint8).reshape(-1, 4)[:, :3].tobytes()
    else:
        raw = frames.astype(f"<i{width}").tobytes()
    with wave.open(str(path), "wb") as w:
        w.setnchannels(frames.shape[1])
        w.setsampwidth(width)
        w.setframerate(rate_hz)
        w.writeframes(raw)
    return path


@pytest.mark.parametrize(("width", "channels"), [(1, 2), (2, 1), (2, 2), (3, 2), (4, 1)])
def test_a_pcm_wav_reads_as_before(width: int, channels: int, tmp_path: Path) -> None:
    full = 1 << (8 * width - 1)
    frames = np.random.default_rng(width).integers(-full, full, (700, channels))
    samples, rate = read_wav(_pcm(tmp_path / "take.wav", frames, width, 22050))
    assert rate == 22050
    expected = frames.astype(np.float64) / float(full)
    np.testing.assert_array_equal(samples, expected.mean(axis=1) if channels > 1 else expected[:, 0])


def test_write_wav_round_trips(tmp_path: Path) -> None:
    ints = np.random.default_rng(0).integers(-32768, 32768, 1000).astype(np.int16)
    samples, rate = read_wav(write_wav(tmp_path / "out.wav", ints, 16000))
    assert rate == 16000
    np.testing.assert_array_equal(samples, ints / 32768.0)


@POSIX
def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    fifo = tmp_path / "take.wav"
    os.mkfifo(fifo)
    err = settle(lambda: read_wav(fifo), fifo)
    assert isinstance(err, SpeechError)
    assert str(err) == f"{fifo}: a pipe (FIFO), not a regular file; expected a WAV file"


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_device_and_a_directory_are_refused(tmp_path: Path) -> None:
    zero = tmp_path / "zero.wav"
    zero.symlink_to("/dev/zero")
    with pytest.raises(SpeechError) as info:
        read_wav(zero)
    assert str(info.value) == f"{zero}: a device, not a regular file; expected a WAV file"
    with pytest.raises(SpeechError) as info:
        read_wav(tmp_path)
    assert str(info.value) == f"{tmp_path}: a directory, not a regular file; expected a WAV file"


def test_a_file_over_the_limit_is_refused_unopened(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_wav(tmp_path / "take.wav", np.zeros(4000, np.int16), 16000)
    monkeypatch.setattr(audio, "AUDIO_LIMIT_BYTES", 1024)

    def no_open(*args: object, **kwargs: object) -> int:
        raise AssertionError("a file over the limit was opened")

    monkeypatch.setattr(boundedfile.os, "open", no_open)
    with pytest.raises(SpeechError) as info:
        read_wav(path)
    assert str(info.value) == f"{path}: 7 KiB; a WAV file is at most 1 KiB"


def test_the_real_limit_reads_as_a_size(tmp_path: Path) -> None:
    huge = tmp_path / "huge.wav"
    with huge.open("wb") as fh:  # sparse: 2.1 GiB declared, no blocks written
        fh.truncate(2_254_857_830)
    with pytest.raises(SpeechError) as info:
        read_wav(huge)
    assert str(info.value) == f"{huge}: 2.1 GiB; a WAV file is at most 512 MiB"


def test_a_missing_or_broken_file_is_worded_as_before(tmp_path: Path) -> None:
    with pytest.raises(SpeechError, match=r"missing\.wav: cannot read as a PCM WAV file \(\[Errno 2\]"):
        read_wav(tmp_path / "missing.wav")
    (tmp_path / "notes.wav").write_text("not audio")
    with pytest.raises(SpeechError, match=r"notes\.wav: cannot read as a PCM WAV file \(file does not start"):
        read_wav(tmp_path / "notes.wav")


@POSIX
def test_lipsync_refuses_a_fifo_recording(tmp_path: Path) -> None:
    """`servoface lipsync take.wav` on a FIFO: exit 2 and one line naming it, not a hang or a traceback."""
    os.mkfifo(tmp_path / "take.wav")
    proc = subprocess.run(
        [sys.executable, "-m", "servoface.controller.cli", "lipsync", "take.wav", "--no-video", "--out", "out"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,  # a regression that waits on the FIFO fails here instead of hanging
        env={**os.environ, "PYOPENGL_PLATFORM": "egl"},
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == "servoface lipsync: take.wav: a pipe (FIFO), not a regular file; expected a WAV file\n"
