"""`servoface demo` end to end on a SHORT script (the full 14 s performance is `make demo`): the emulated
chain plays it with wire time on, and the twin video, contact sheet, clipped frame and report are written."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import servoface.controller.demo as demo
from PIL import Image
from servoface.controller.cli import main

SHORT = """
[script]
face = "human"
title = "demo smoke: a quick smile and an unsafe jaw snap"
end_s = 0.7

[poses]
smile = { AU6 = 0.2, AU12 = 0.4 }
snap = { AU27 = 1.0, AU26 = 1.0, AU51 = 1.0 }

[expressions.smile]
duration_s = 0.3
movements = [{ pose = "smile", percent = 100, easing = "min_jerk" }]

[expressions.snap]
duration_s = 0.2
movements = [{ pose = "snap", percent = 10 }, { pose = "snap", percent = 90 }]

[[play]]
at_s = 0.0
sequence = ["smile", "snap"]

[blink]
enabled = false
"""


@pytest.fixture
def short_demo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    script = tmp_path / "short.toml"
    script.write_text(SHORT)
    monkeypatch.setitem(demo.DEMO_SCRIPTS, "human", script)
    return tmp_path / "out"


def test_demo_cli_writes_video_sheet_clip_and_report(short_demo: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = main(["demo", "--out", str(short_demo), "--format", "gif"])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    report = json.loads((short_demo / "report.json").read_text())
    assert report["head"] == "human" and report["script"] == "short.toml"
    assert report["frames"] >= 10 and sum(report["verdicts"].values()) == report["frames"]
    assert report["verdicts"]["clip"] + report["verdicts"]["reject"] > 0  # the jaw snap is too fast
    assert report["clip_reasons"] and report["bus"]["bytes_written"] > 0
    assert "Indirect Data at 224" in report["bus"]["positions"]  # the position sentinel, on the mixed chain
    assert "Fast Sync Read" in report["bus"]["read"]
    assert report["max_goal_error_tick"] is not None and report["max_goal_error_tick"] <= 1
    assert set(report["goal_error_tick"]) == {str(i) for i in range(1, 31)}
    gif = Image.open(short_demo / "twin.gif")
    n_video = report["outputs"]["video_frames"]
    assert n_video >= 10
    total_ms = 0
    n_stored = int(getattr(gif, "n_frames", 1))
    for k in range(n_stored):  # holds may be stored once with their durations added
        gif.seek(k)
        total_ms += gif.info["duration"]
    assert total_ms == pytest.approx(n_video * 50, abs=2 * n_stored)
    sheet = np.asarray(Image.open(short_demo / "sheet.png").convert("RGB"))
    assert sheet.std() > 5  # a drawn face, not a blank image
    assert len(report["outputs"]["sheet_expressions"]) >= 10
    assert report["outputs"]["clipped_frame"] == "clipped.png"
    clipped = np.asarray(Image.open(short_demo / "clipped.png").convert("RGB"))
    left, right = np.array_split(clipped, 2, axis=1)
    assert np.abs(left.astype(int) - right.astype(int)).mean() > 0.5  # target and gated faces differ
    assert "report" in out and "twin.gif" in out


def test_demo_cli_rejects_a_bad_rate(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["demo", "--out", str(tmp_path), "--rate", "0"]) == 2
    assert "--rate" in capsys.readouterr().err
    assert not (tmp_path / "report.json").exists()
