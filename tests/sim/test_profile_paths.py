"""Paths a profile names stay inside its folder: a profile cannot make servoface read or overwrite a file
elsewhere (``servoface calibrate --head PROFILE --builtin`` writes the calibration file the profile names)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from servoface.controller.cli import main
from servoface.sim.errors import HeadProfileError
from servoface.sim.heads import load_head

ROOT = Path(__file__).resolve().parents[2]


def _profile(tmp_path: Path, calibration: str) -> Path:
    folder = tmp_path / "head"
    shutil.copytree(ROOT / "sim/heads/human", folder)
    toml = folder / "head.toml"
    text = toml.read_text()
    assert 'calibration = "calibration.json"' in text
    toml.write_text(text.replace('calibration = "calibration.json"', f'calibration = "{calibration}"'))
    return folder


@pytest.mark.parametrize("where", ["../outside.json", "/tmp/servoface-outside.json", "sub/../../outside.json"])
def test_a_calibration_path_outside_the_folder_is_refused(tmp_path: Path, where: str) -> None:
    folder = _profile(tmp_path, where)
    with pytest.raises(HeadProfileError, match="inside the profile folder"):
        load_head(folder)


def test_calibrate_builtin_cannot_overwrite_a_file_outside(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    victim = tmp_path / "outside.json"
    victim.write_text("precious")
    folder = _profile(tmp_path, "../outside.json")
    assert main(["calibrate", "--head", str(folder), "--builtin"]) == 2
    assert victim.read_text() == "precious"
    assert "inside the profile folder" in capsys.readouterr().err


def test_a_path_inside_is_fine(tmp_path: Path) -> None:
    folder = _profile(tmp_path, "calibration.json")
    assert load_head(folder).calibration_path == folder / "calibration.json"
