"""`servoface preview`: real renders at small sizes, and every input error with exit code 2."""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image as PILImage
from servoface.controller.cli import main
from servoface.sim.render import egl_missing_reason

SMALL = ["--size", "96x72", "--quiet"]


def _needs_egl() -> None:
    reason = egl_missing_reason()
    if reason is not None:
        pytest.skip(reason)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["preview", "-o", "x.png"], "one expression name, or --all"),
        (["preview", "joy", "--all", "-o", "x.png"], "one expression name, or --all"),
        (["preview", "joy", "-o", "x.bmp"], "must end in .png"),
        (["preview", "joy", "-o", "x"], "no extension"),
        (["preview", "--all", "-o", "x.gif"], "a sheet must end in .png"),
        (["preview", "joy", "-o", "no/such/folder/x.png"], "does not exist"),
        (["preview", "joy", "-o", "x.png", "--size", "640"], "--size"),
        (["preview", "joy", "-o", "x.png", "--size", "5x5"], "--size"),
        (["preview", "joy", "-o", "x.gif", "--fps", "0"], "fps"),
        (["preview", "joy", "-o", "x.mp4", "--duration", "-1"], "duration"),
        (["preview", "--all", "-o", "x.png", "--columns", "0"], "--columns"),
    ],
)
def test_bad_arguments_exit_2_and_write_nothing(
    argv: list[str],
    message: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_unknown_head_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "x.png"
    assert main(["preview", "joy", "--head", "cat", "-o", str(out), *SMALL]) == 2
    assert "--head cat: expected a built-in head name" in capsys.readouterr().err
    assert not out.exists()


def test_unknown_expression_exits_2_and_lists_the_library(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "x.png"
    assert main(["preview", "no_such_face", "--head", "human", "-o", str(out), *SMALL]) == 2
    err = capsys.readouterr().err
    assert "unknown expression 'no_such_face'" in err and "neutral" in err
    assert not out.exists()


def _some_expression(face_type: str) -> str:
    from servoface.sim.expressions import load_library

    names = [n for n in load_library(face_type) if n != "neutral"]
    return names[0]


@pytest.mark.parametrize("head", ["human", "dog"])
def test_still_png_at_apex(head: str, tmp_path: Path) -> None:
    _needs_egl()
    name = _some_expression(head)
    apex, neutral = tmp_path / "apex.png", tmp_path / "neutral.png"
    assert main(["preview", name, "--head", head, "-o", str(apex), *SMALL]) == 0
    assert main(["preview", "neutral", "--head", head, "-o", str(neutral), *SMALL]) == 0
    a, n = np.asarray(PILImage.open(apex)), np.asarray(PILImage.open(neutral))
    assert a.shape == (72, 96, 3)
    assert np.abs(a.astype(int) - n).mean() > 0.5


def test_gif_and_mp4_clips_have_the_frames_asked_for(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _needs_egl()
    name = _some_expression("human")
    gif, mp4 = tmp_path / "clip.gif", tmp_path / "clip.mp4"
    clip = ["--duration", "1.0", "--fps", "10", "--view", "three-quarter"]
    assert main(["preview", name, "--head", "human", "-o", str(gif), *SMALL, *clip]) == 0
    assert main(["preview", name, "--head", "human", "-o", str(mp4), *SMALL, *clip]) == 0
    assert "10 frames" in capsys.readouterr().out
    with PILImage.open(gif) as im:
        # identical neutral hold frames may be merged by the GIF encoder; total time is kept
        durations = []
        for i in range(im.n_frames):
            im.seek(i)
            durations.append(im.info["duration"])
        assert 3 <= im.n_frames <= 10 and sum(durations) == 1000 and im.size == (96, 72)
    reader = imageio.get_reader(str(mp4))
    try:
        assert reader.count_frames() == 10
        frames = [reader.get_data(i) for i in (0, 5)]
    finally:
        reader.close()
    assert np.abs(frames[0].astype(int) - frames[1]).mean() > 0.3  # the apex differs from the start


def test_all_writes_a_labelled_sheet(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _needs_egl()
    from servoface.sim.expressions import load_library

    out = tmp_path / "sheet.png"
    assert main(["preview", "--all", "--head", "dog", "-o", str(out), *SMALL, "--columns", "4"]) == 0
    printed = capsys.readouterr().out
    n = len({"neutral", *load_library("dog")})
    assert f"{n} expressions" in printed and printed.split(": ", 2)[2].startswith("neutral")
    sheet = np.asarray(PILImage.open(out))
    rows = -(-n // 4)
    assert sheet.shape[1] == 4 * 96 + 5 * 4 and sheet.shape[0] > rows * 72
