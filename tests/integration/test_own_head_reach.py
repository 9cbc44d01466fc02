"""A joint range that reaches more than half a turn from neutral, through the command line as a builder
meets it: `check` passed it (its span is under one turn) and `calibrate --template` / `--builtin`, which put
neutral at tick 2048, then refused it ("outside 0..4095; re-mount the horn"). Now `check` names it first,
and flags a range exactly when those two refuse it (a servo on the head's right side turns the other way,
so the same range may fit there)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from servoface.controller.cli import main

from tests.cli_run import run_cli

# role -> (its joint's index, the joint's limits, how many joints before it have the same limits)
MECH_JOINTS = {"jaw": (1, "[0.0, 25.0]", 0), "lid_r": (5, "[-15.0, 70.0]", 1)}


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("reach") / "mine"
    assert main(["new", str(folder), "--from", "mechanical"]) == 0
    return folder


def _head(pristine: Path, tmp_path: Path, role: str, limits: str) -> Path:
    folder = tmp_path / "mine"
    shutil.copytree(pristine, folder)
    text = (folder / "head.toml").read_text()
    _, was, before = MECH_JOINTS[role]
    parts = text.split(f"limits_deg = {was}")
    assert len(parts) > before + 1
    head = f"limits_deg = {was}".join(parts[: before + 1])
    tail = f"limits_deg = {was}".join(parts[before + 1 :])
    (folder / "head.toml").write_text(f"{head}limits_deg = {limits}{tail}")
    return folder


def test_check_names_the_end_past_half_a_turn_as_calibrate_would_refuse_it(
    pristine: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _head(pristine, tmp_path, "jaw", "[0.0, 200.0]")
    status, out, _ = run_cli(["check", str(folder), "--no-report"], capsys)
    assert status == 1, out
    key = f"{folder / 'head.toml'}: joint[1].limits_deg"
    line = next((ln for ln in out.splitlines() if "limits_deg" in ln), "")
    assert line.startswith(f"problem: {key}: expected both ends within 0..4095 of a servo turning with the joint"), out
    assert "for servo 'jaw', got [0, 200] with neutral 0 deg (the upper end, 200 deg from neutral, lands on " in line
    assert "tick 4324, past 4095: that side has 2047 ticks (179.9 deg);" in line, line
    assert "re-mount the horn so neutral sits nearer the middle of the travel" in line, line
    assert "2 problem(s); fix them and run `servoface check" in out, out  # and: no calibration yet

    template = folder / "calibration_template.csv"
    before = template.read_text()
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--template", "--force"], capsys)
    assert status == 2 and f"servoface calibrate: --template: {key}: expected both ends within" in err, err
    assert "nothing written" in err and template.read_text() == before
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--builtin"], capsys)
    # the same words as check's, the end that does not fit and the fix (was "outside 0..4095; re-mount the horn")
    assert status == 2 and line.removeprefix(f"problem: {key}: ") in err, err
    assert not (folder / "calibration.json").exists()


@pytest.mark.parametrize(
    ("role", "limits", "refused"),
    [
        ("jaw", "[-179.9, 180.0]", True),  # the report: 180 deg up from tick 2048 is 4096
        ("jaw", "[-180.0, 179.9]", False),  # ticks 0..4095
        ("jaw", "[-180.05, 0.0]", True),  # tick -0.57 rounds to -1
        ("jaw", "[-180.04, 0.0]", False),  # tick -0.46 rounds to 0
        ("jaw", "[0.0, 179.95]", False),  # tick 4095.43 rounds to 4095
        ("jaw", "[0.0, 179.96]", True),  # tick 4095.55 rounds to 4096
        ("jaw", "[0.0, 0.04]", True),  # one tick
        ("jaw", "[0.0, 0.05]", False),  # 2048..2049
        ("lid_r", "[-179.9, 180.0]", False),  # a right-side servo is reversed: 180 deg goes down to tick 0
        ("lid_r", "[-180.0, 179.9]", True),  # and -180 deg up to 4096
    ],
)
def test_check_flags_a_range_exactly_when_calibrate_refuses_it(
    pristine: Path, tmp_path: Path, role: str, limits: str, refused: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _head(pristine, tmp_path, role, limits)
    _, out, _ = run_cli(["check", str(folder), "--no-report"], capsys)
    flagged = [ln for ln in out.splitlines() if f"joint[{MECH_JOINTS[role][0]}].limits_deg" in ln]
    assert len(flagged) <= 1 and all(ln.startswith("problem: ") for ln in flagged), out
    template, _, _ = run_cli(
        ["calibrate", "--head", str(folder), "--template", "--out", str(tmp_path / "t.csv")], capsys
    )
    builtin, _, err = run_cli(["calibrate", "--head", str(folder), "--builtin"], capsys)
    assert template == builtin and builtin in (0, 2), err
    assert bool(flagged) == (builtin == 2) == refused, (out, err)
