"""`speech.video.mux` writes the talking-head video all or nothing (`sim.render.atomic`): ffmpeg failing
leaves no file at the target, no hidden temporary beside it, and a video already there as it was."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from servoface.controller.speech.audio import write_wav
from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.video import mux
from servoface.sim.render.video import write_mp4


def _silent_video(path: Path) -> Path:
    frames = [np.full((64, 64, 3), 40 * k, dtype=np.uint8) for k in range(6)]
    write_mp4(frames, path, fps=12)
    return path


def test_a_mux_writes_the_video_with_its_sound(tmp_path: Path) -> None:
    video = _silent_video(tmp_path / "silent.mp4")
    wav = tmp_path / "sound.wav"
    write_wav(wav, np.zeros(8000, dtype=np.int16), 16000)
    out = mux(video, wav, tmp_path / "talk.mp4")
    assert out.stat().st_size > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["silent.mp4", "sound.wav", "talk.mp4"]


@pytest.mark.parametrize("already", [False, True])
def test_a_failed_mux_leaves_nothing_and_an_old_video_unchanged(tmp_path: Path, already: bool) -> None:
    video = _silent_video(tmp_path / "silent.mp4")
    bad = tmp_path / "sound.wav"
    bad.write_bytes(b"not a sound at all")
    out = tmp_path / "talk.mp4"
    if already:
        out.write_bytes(b"the last good video")
    with pytest.raises(SpeechError, match="ffmpeg could not mux the audio"):
        mux(video, bad, out)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(["silent.mp4", "sound.wav"] + (["talk.mp4"] if already else [])), names
    if already:
        assert out.read_bytes() == b"the last good video"


def test_an_ffmpeg_that_dies_after_writing_part_leaves_no_truncated_video(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """ffmpeg killed mid-mux (out of disk, a signal) has already written part of its output: that part is
    the hidden temporary's, removed, never the target's. (ffmpeg stood in for by a function that writes half
    a file where it was told to and fails.)"""
    import subprocess

    from servoface.controller.speech import video as video_module

    def dies_halfway(cmd: list[str], **kwargs: object) -> subprocess.CompletedProcess[str]:
        Path(cmd[-1]).write_bytes(b"\x00\x00\x00\x18ftypmp42 half a video")
        return subprocess.CompletedProcess(cmd, 1, "", "Killed")

    monkeypatch.setattr(video_module.subprocess, "run", dies_halfway)
    out = tmp_path / "talk.mp4"
    out.write_bytes(b"the last good video")
    with pytest.raises(SpeechError, match="Killed"):
        mux(tmp_path / "silent.mp4", tmp_path / "sound.wav", out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["talk.mp4"]
    assert out.read_bytes() == b"the last good video"
