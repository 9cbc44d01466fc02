"""Calibration messages a builder meets on a new head (`servoface new mine --from mechanical`), through the
command line:

- a measured CSV whose ticks go the wrong way once was told "not strictly decreasing" for a servo whose
  ticks rise (the direction was read from its first step): now the step is named with what it does and the
  direction the servo's other steps give;
- a joint range of a few ticks (``limits_deg = [0, 0.05]``) got a template with rows on one tick (2048,
  2048, ...) that ``calibrate --csv`` then refused; a range on one tick was refused by ``--builtin`` with
  "the measured ticks do not change with the target; re-measure" though nothing was measured;
- ``--builtin`` refused an end past 0..4095 with "outside 0..4095; re-mount the horn" only: now in check's
  words (the end that does not fit, the fix).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from servoface.controller.cli import main

from tests.cli_run import run_cli


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("messages") / "mine"
    assert main(["new", str(folder), "--from", "mechanical"]) == 0
    return folder


def _head(pristine: Path, tmp_path: Path, jaw_limits: str | None = None) -> Path:
    folder = tmp_path / "mine"
    shutil.copytree(pristine, folder)
    if jaw_limits is not None:
        text = (folder / "head.toml").read_text()
        assert text.count("limits_deg = [0.0, 25.0]") == 1  # the jaw, joint[1]
        (folder / "head.toml").write_text(text.replace("limits_deg = [0.0, 25.0]", f"limits_deg = {jaw_limits}"))
    return folder


@pytest.mark.parametrize(
    ("row", "edited", "says"),
    [
        # the jaw rises (2048 at 0 deg .. 2332 at 25 deg); its first step measured falling
        (
            "jaw,6.25,2119",
            "jaw,6.25,2000",
            "role 'jaw': ticks fall from 2048 (line 6, target 0) to 2000 (line 7, target 6.25), but this "
            "servo's ticks rise with the target (3 of its 4 steps; 2048 at target 0 -> 2332 at target 25): "
            "expected ticks strictly increasing in the target; re-measure line 6 or line 7",
        ),
        # brow_r is on the right: its ticks fall; one step measured rising
        (
            "brow_r,5,1991",
            "brow_r,5,2100",
            "role 'brow_r': ticks rise from 2048 (line 19, target 0) to 2100 (line 20, target 5), but this "
            "servo's ticks fall with the target (4 of its 5 steps; 2162 at target -10 -> 1820 at target 20): "
            "expected ticks strictly decreasing in the target; re-measure line 19 or line 20",
        ),
    ],
)
def test_a_csv_step_the_wrong_way_says_what_was_found_and_expected(
    pristine: Path, tmp_path: Path, row: str, edited: str, says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _head(pristine, tmp_path)
    csv = tmp_path / "measured.csv"
    text = (folder / "calibration_template.csv").read_text()
    assert f"\n{row}\n" in text
    csv.write_text(text.replace(f"\n{row}\n", f"\n{edited}\n"))
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--csv", str(csv)], capsys)
    assert status == 2, err
    assert f"servoface calibrate: {csv}: line " in err and says in err, err
    assert not (folder / "calibration.json").exists()


@pytest.mark.parametrize("limits", ["[0.0, 0.05]", "[-0.05, 0.05]", "[0.0, 0.2]"])
def test_calibrate_takes_the_unedited_template_of_a_range_of_a_few_ticks(
    pristine: Path, tmp_path: Path, limits: str, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _head(pristine, tmp_path, limits)
    status, out, _ = run_cli(["check", str(folder), "--no-report"], capsys)
    assert "limits_deg" not in out, out  # check takes it: so must calibrate
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--template", "--force"], capsys)
    assert status == 0, err
    template = folder / "calibration_template.csv"
    ticks = [int(ln.split(",")[2]) for ln in template.read_text().splitlines() if ln.startswith("jaw,")]
    assert len(ticks) == len(set(ticks)) >= 2 and ticks == sorted(ticks), ticks
    status, out, err = run_cli(["calibrate", "--head", str(folder), "--csv", str(template)], capsys)
    assert status == 0, err
    assert "resolution will be poor" in out, out  # the warning calibrate gives a range of a few ticks


def test_a_range_on_one_tick_is_refused_with_the_fix_not_re_measure(
    pristine: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _head(pristine, tmp_path, "[0.0, 0.04]")
    _, out, _ = run_cli(["check", str(folder), "--no-report"], capsys)
    key = f"{folder / 'head.toml'}: joint[1].limits_deg"
    line = next((ln for ln in out.splitlines() if "limits_deg" in ln), "")
    assert line.startswith(
        f"problem: {key}: expected its ends on two different ticks of a servo turning with the joint "
        "(4096 ticks a turn; any span of 0.088 deg or more is)"
    ), out
    reason = line.removeprefix(f"problem: {key}: ")
    assert "(spans 0.04 deg, less than one servo tick (0.46 tick): both ends land on tick 2048; a typo? " in reason
    assert "widen the range to at least 0.088 deg, or gear the joint" in reason, reason
    for how in (["--builtin"], ["--template", "--force"]):
        status, _, err = run_cli(["calibrate", "--head", str(folder), *how], capsys)
        assert status == 2 and reason in err, err
        assert "re-measure" not in err and "do not change with the target" not in err, err
    assert not (folder / "calibration.json").exists()


def test_builtin_names_the_profile_key_of_a_range_it_refuses(
    pristine: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _head(pristine, tmp_path, "[0.0, 200.0]")
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--builtin"], capsys)
    assert status == 2 and f"{folder / 'head.toml'}: joint[1].limits_deg: expected both ends within" in err, err
