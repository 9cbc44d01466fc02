"""A builder's head.toml changed after `servoface new`, and the messages on the way: what went wrong, each
found by doing it through the command line as a builder would.

- no command wrote `calibration_template.csv` again after head.toml lost or gained a servo, so
  `calibrate --csv` refused the old rows with no way forward (now `calibrate --template`, which never
  replaces a template without `--force`: it may hold the builder's measurements);
- `check` passed a joint whose range spans more than one servo turn or less than one tick, which
  `calibrate` then refused;
- `check` exited 1 on a head.toml it could not read, where every other command exits 2 for bad input;
- messages named the head twice (`check: DIR/: DIR/head.toml: ...`), the library table of `check` went out
  of line for a long expression name, and interactive `calibrate` left its prompt without a newline when
  the input ended.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest
from servoface.controller.cli import main

from tests.cli_run import run_cli
from tests.integration import own_heads as oh


def _new(folder: Path) -> Path:
    assert main(["new", str(folder), "--from", "mechanical"]) == 0
    return folder


def _without_actuator(folder: Path, role: str) -> None:
    blocks = re.split(r"(?m)^(?=\[)", (folder / "head.toml").read_text())
    kept = [b for b in blocks if not (b.startswith("[[actuator]]") and re.search(rf'(?m)^role = "{role}"', b))]
    assert len(kept) == len(blocks) - 1
    (folder / "head.toml").write_text("".join(kept))


TAIL = """
[[joint]]
name = "tail"
pivot_mm = [0.0, 60.0, -80.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-30.0, 30.0]

[[actuator]]
role = "tail"
servo = { id = 9, model = "XL330-M288" }
kind = "joint"
"""


def _roles_in(csv: Path) -> set[str]:
    return {ln.split(",")[0] for ln in csv.read_text().splitlines() if ln and not ln.startswith(("#", "role,"))}


def _with_jaw_limits(folder: Path, limits: str) -> None:
    text = (folder / "head.toml").read_text()
    assert "limits_deg = [0.0, 25.0]" in text  # the mechanical head's jaw: joint[1]
    (folder / "head.toml").write_text(text.replace("limits_deg = [0.0, 25.0]", f"limits_deg = {limits}", 1))


# --- 1. the template, written again for an edited head.toml ---------------------------------------------


def test_template_is_written_again_for_an_edited_head_but_never_over_one_without_force(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _new(tmp_path / "mine")
    template = folder / "calibration_template.csv"
    _without_actuator(folder, "eye_tilt")  # the builder took the eye-tilt servo out and added a tail
    (folder / "head.toml").write_text((folder / "head.toml").read_text() + TAIL)

    status, _, err = run_cli(["calibrate", "--head", str(folder), "--csv", str(template)], capsys)
    assert status == 2 and not (folder / "calibration.json").exists()
    assert f"servoface calibrate --head {folder} --template --out NEW.csv" in err, err  # the way forward
    assert f"--template --force` replaces {template}" in err, err

    measured = template.read_text().replace("jaw,25,2332", "jaw,25,2340")  # the builder's own ticks
    template.write_text(measured)
    status, out, err = run_cli(["calibrate", "--head", str(folder), "--template"], capsys)
    assert status == 2
    assert f"{template} exists already" in err and "--force" in err and "nothing written" in err, err
    assert template.read_text() == measured

    status, out, err = run_cli(["calibrate", "--head", str(folder), "--template", "--force"], capsys)
    assert status == 0, err
    assert f"to {template}" in out
    assert _roles_in(template) == {"jaw", "brow_l", "brow_r", "lid_l", "lid_r", "eye_pan", "neck_pan", "tail"}
    assert not list(folder.glob(".*.tmp"))  # written whole, no temporary left behind
    status, out, err = run_cli(["calibrate", "--head", str(folder), "--csv", str(template)], capsys)
    assert status == 0, err
    assert (folder / "calibration.json").is_file()


def test_template_out_and_roles_write_only_those_rows_beside_the_old_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _new(tmp_path / "mine")
    before = (folder / "calibration_template.csv").read_text()
    assert main(["calibrate", "--head", str(folder), "--csv", str(folder / "calibration_template.csv")]) == 0
    (folder / "head.toml").write_text((folder / "head.toml").read_text() + TAIL)
    extra = folder / "tail.csv"
    status, _, err = run_cli(
        ["calibrate", "--head", str(folder), "--template", "--roles", "tail", "--out", str(extra)], capsys
    )
    assert status == 0, err
    assert _roles_in(extra) == {"tail"}
    assert (folder / "calibration_template.csv").read_text() == before
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--roles", "tail", "--csv", str(extra)], capsys)
    assert status == 0, err
    status, out, err = run_cli(["check", str(folder), "--no-report"], capsys)
    assert "calibration has no servo for role" not in out


def test_template_refuses_bad_input_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _new(tmp_path / "mine")
    template = folder / "calibration_template.csv"
    before = template.read_text()
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--csv", str(template), "--force"], capsys)
    assert status == 2 and "--force: only with --template" in err
    assert not (folder / "calibration.json").exists()
    missing = tmp_path / "no_such_folder" / "t.csv"
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--template", "--out", str(missing)], capsys)
    assert status == 2 and str(missing) in err
    assert not missing.parent.exists()
    _with_jaw_limits(folder, "[-200.0, 200.0]")
    status, _, err = run_cli(["calibrate", "--head", str(folder), "--template", "--force"], capsys)
    assert status == 2
    assert f"{folder / 'head.toml'}: joint[1].limits_deg: expected a span of at most 359.9 deg" in err, err
    assert "nothing written" in err and "Traceback" not in err
    assert template.read_text() == before


# --- 2. check: a range no servo turn can measure ---------------------------------------------------------


@pytest.mark.parametrize(
    ("limits", "got", "expected", "why"),
    [
        ("[-200.0, 200.0]", "[-200, 200]", "a span of at most 359.9 deg", "spans 400 deg, more than one servo turn"),
        # 0.04 deg: both ends round to tick 2048 (0.05 deg would reach 2049: calibrate takes it, with a warning)
        ("[0.0, 0.04]", "[0, 0.04]", "its ends on two different ticks", "spans 0.04 deg, less than one servo tick"),
    ],
)
def test_check_names_a_joint_range_calibrate_would_refuse(
    tmp_path: Path, limits: str, got: str, expected: str, why: str, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _new(tmp_path / "mine")
    _with_jaw_limits(folder, limits)
    status, out, err = run_cli(["check", str(folder), "--no-report"], capsys)
    assert status == 1, out + err
    line = next((ln for ln in out.splitlines() if "joint[1].limits_deg" in ln), "")
    assert line.startswith(f"problem: {folder / 'head.toml'}: joint[1].limits_deg: expected {expected}"), line
    assert f"for servo 'jaw', got {got} ({why}" in line, line


def test_check_names_range_deg_when_the_actuator_sets_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _new(tmp_path / "mine")
    text = (folder / "head.toml").read_text()
    text = text.replace('joints = ["jaw"]', 'joints = ["jaw"]\nrange_deg = [0.0, 0.01]', 1)
    (folder / "head.toml").write_text(text)
    status, out, _ = run_cli(["check", str(folder), "--no-report"], capsys)
    assert status == 1
    assert f"problem: {folder / 'head.toml'}: actuator[0].range_deg: expected its ends on two different ticks" in out, (
        out
    )


def test_a_geared_joint_calibrated_from_measurements_is_not_a_problem(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """400 deg of joint on 2000 ticks (geared 1:2): the measured calibration settles what the span rule
    (a servo turning with its joint) can only guess before calibration."""
    folder = _new(tmp_path / "mine")
    _with_jaw_limits(folder, "[-200.0, 200.0]")
    rows = [ln for ln in (folder / "calibration_template.csv").read_text().splitlines() if not ln.startswith("jaw,")]
    rows += ["jaw,-200,1048", "jaw,-100,1548", "jaw,0,2048", "jaw,100,2548", "jaw,200,3048"]
    geared = tmp_path / "geared.csv"
    geared.write_text("\n".join(rows) + "\n")
    assert main(["calibrate", "--head", str(folder), "--csv", str(geared)]) == 0
    status, out, _ = run_cli(["check", str(folder), "--no-report"], capsys)
    assert "expected a span" not in out


# --- 3 and 4. exit code and message of a profile that cannot be read -------------------------------------


@pytest.mark.parametrize("suffix", ["", "/"])
def test_check_a_head_toml_it_cannot_parse_is_bad_input_named_once(
    tmp_path: Path, suffix: str, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _new(tmp_path / "mine")
    _with_jaw_limits(folder, "[0.0, 25.0,")  # an unfinished edit
    arg = str(folder) + suffix
    status, out, err = run_cli(["check", arg], capsys)
    assert status == 2  # the README's rule: bad input (a malformed profile) is 2, as for every command
    first = err.splitlines()[0]
    assert first.startswith(f"servoface check: {folder / 'head.toml'}: not valid TOML"), first
    assert first.count(str(folder)) == 1, first
    assert out == ""
    status, _, err = run_cli(["preview", "happiness", "--head", arg, "-o", str(tmp_path / "x.png")], capsys)
    assert status == 2
    assert err.splitlines()[0].count(str(folder)) == 1, err
    assert not (tmp_path / "x.png").exists()


def test_a_folder_that_is_not_there_is_named_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    arg = str(tmp_path / "nosuch") + "/"
    status, _, err = run_cli(["check", arg], capsys)
    assert status == 2
    first = err.splitlines()[0]
    assert first.count(str(tmp_path / "nosuch")) == 1, first


# --- 4. the library table, the end of input -------------------------------------------------------------

LONG_NAME = "brows_up_and_jaw_dropped_wide"
LIBRARY = f"""schema_version = 1
face_type = "human"

[neutral]
source = "rest"
aus = {{}}

[surprise]
source = "mine"
aus = {{ AU1 = 1.0, AU2 = 1.0, AU26 = 1.0 }}

[{LONG_NAME}]
source = "mine"
aus = {{ AU1 = 1.0, AU2 = 1.0, AU27 = 1.0 }}

[blink]
source = "mine"
aus = {{ AU45 = 1.0 }}
"""


def test_the_library_table_stays_in_line_for_a_long_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _new(tmp_path / "mine")
    (folder / "faces.toml").write_text(LIBRARY)
    text = (folder / "head.toml").read_text()
    (folder / "head.toml").write_text(
        text.replace('au_direct = "direct.toml"', 'expressions = "faces.toml"\nau_direct = "direct.toml"', 1)
    )
    status, out, err = run_cli(["check", str(folder)], capsys)
    assert status == 1, out + err  # not calibrated yet; the report still runs
    lines = out.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("library expressions (3,"))
    rows = lines[start + 1 : start + 4]
    assert {r.split()[0] for r in rows} == {"surprise", LONG_NAME, "blink"}, rows
    columns = {r.index("%") for r in rows}
    assert len(columns) == 1, "\n".join(rows)


def test_calibrate_ending_on_end_of_input_ends_the_prompt_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = oh.write_mechanical(tmp_path / "m")
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # Ctrl-D, or a script whose input ran out
    status, out, err = run_cli(["calibrate", "--head", str(folder), "--emulate", "--roles", "jaw"], capsys)
    assert status == 1 and "nothing saved" in err
    assert out.endswith("(Enter to capture): \n"), repr(out[-80:])
    assert not (folder / "calibration.json").exists()
