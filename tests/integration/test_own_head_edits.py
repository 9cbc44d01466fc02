"""A builder's own head after editing: what broke when a head unlike the built-ins went down the documented
path (`new` → edit head.toml → `calibrate --csv` → `check` → `play`), each found by doing it as a user would.

- a servo model the profile schema lists (MX-28) but the twin gate had no speed for: `check` and `preview`
  refused every head that used it;
- files saved in another encoding than UTF-8, or with the byte-order mark a spreadsheet's "CSV UTF-8" export
  writes: a traceback (the CSV, an own AU table) or a codec message with a byte offset and no file name;
- a misspelt key named the nearest one nowhere;
- `check` scored an expression "of the rest" with the AUs it cannot show still in the target, when their
  joint is in the profile but no servo drives it (0 % of the rest for a head that shows all of the rest);
- `new` overwrote the builder's own meshes and measured CSV without --force, and `new ''` wrote into `.`;
- `calibrate --roles X --csv` (what `check` tells you to run) refused the template's other rows;
- a direct table naming servos the head lost blamed "no targets"; a row [AU99] passed silently;
- `preview` named no nearest expression; `play` before `calibrate` named no next step;
- the model name `scan` prints (MX-28(2.0)) was refused in head.toml.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from servoface.controller.cli import main
from servoface.controller.new_head import write_template_csv
from servoface.sim.gate.limits import rate_caps_tick

from tests.integration import own_heads as oh

LATIN1 = "m\xe2choire".encode("latin-1")  # what a legacy editor saves for "mâchoire"


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    capsys.readouterr()
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out + err


def _calibrated_mechanical(folder: Path) -> Path:
    oh.write_mechanical(folder)
    assert main(["calibrate", "--head", str(folder), "--csv", str(write_template_csv(folder))]) == 0
    return folder


# --- the MX-28 the schema lists -------------------------------------------------------------------------


def test_every_model_a_profile_may_name_has_a_gate_speed() -> None:
    from servoface.sim.rig import SERVO_MODELS

    step, speedup = rate_caps_tick(list(SERVO_MODELS), 0.02, 0.8, 0.1)
    assert (step >= 1).all() and (speedup >= 1).all()
    mx, _ = rate_caps_tick(["MX-28", "MX-28(2.0)"], 0.02, 0.8, 0.1)
    assert mx[0] == mx[1]


def test_a_head_with_an_mx28_servo_checks_clean(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = oh.write_mechanical(tmp_path / "mx")
    text = (folder / "head.toml").read_text()
    first = re.search(r'model = "[^"]+"', text)
    assert first is not None
    (folder / "head.toml").write_text(text[: first.start()] + 'model = "MX-28"' + text[first.end() :])
    assert main(["calibrate", "--head", str(folder), "--csv", str(write_template_csv(folder))]) == 0
    status, out = _run(["check", str(folder), "--no-report"], capsys)
    assert "no speed known" not in out
    assert status == 0, out


# --- encodings ------------------------------------------------------------------------------------------


def test_a_csv_not_in_utf8_is_refused_naming_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = oh.write_mechanical(tmp_path / "m")
    csv = write_template_csv(folder)
    raw = csv.read_bytes()
    bad = tmp_path / "latin1.csv"
    bad.write_bytes(raw + b"# " + LATIN1 + b"\n")
    status, out = _run(["calibrate", "--head", str(folder), "--csv", str(bad)], capsys)
    assert status == 2
    assert "Traceback" not in out
    line = raw.count(b"\n") + 1
    assert f"{bad}: line {line}: not UTF-8 text (byte 0xe2)" in out
    assert not (folder / "calibration.json").exists()


def test_a_csv_with_a_byte_order_mark_is_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = oh.write_mechanical(tmp_path / "m")
    csv = write_template_csv(folder)
    lines = [ln for ln in csv.read_text().splitlines() if not ln.startswith("#")]  # header first, as Excel saves
    bom = tmp_path / "excel.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + ("\r\n".join(lines) + "\r\n").encode())
    status, out = _run(["calibrate", "--head", str(folder), "--csv", str(bom)], capsys)
    assert status == 0, out
    assert (folder / "calibration.json").is_file()


def test_a_profile_not_in_utf8_names_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = oh.write_mechanical(tmp_path / "m")
    text = (folder / "head.toml").read_text().encode()
    (folder / "head.toml").write_bytes(text.replace(b'name = "tinbot"', b'name = "tinbot"\n# ' + LATIN1, 1))
    line = text[: text.index(b'name = "tinbot"')].count(b"\n") + 2
    status, out = _run(["play", "happiness", "--head", str(folder), "--emulate"], capsys)
    assert status == 2
    assert f"head.toml: line {line}: expected UTF-8 text, got byte 0xe2" in out
    assert "codec" not in out


def test_a_profile_with_a_byte_order_mark_loads(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _calibrated_mechanical(tmp_path / "m")
    (folder / "head.toml").write_bytes(b"\xef\xbb\xbf" + (folder / "head.toml").read_bytes())
    status, out = _run(["check", str(folder), "--no-report"], capsys)
    assert status == 0, out


def test_an_own_au_table_not_in_utf8_is_a_problem_not_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _calibrated_mechanical(tmp_path / "m")
    (folder / "aus.toml").write_bytes(b'schema_version = 1\nface_type = "human"\n# ' + LATIN1 + b"\n")
    text = (folder / "head.toml").read_text()
    own = text.replace('au_direct = "direct.toml"', 'au_direct = "direct.toml"\nau_table = "aus.toml"')
    (folder / "head.toml").write_text(own)
    status, out = _run(["check", str(folder)], capsys)
    assert "Traceback" not in out
    assert status == 1
    assert "aus.toml: line 3: expected UTF-8 text, got byte 0xe2" in out


def test_a_script_not_in_utf8_names_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    script = tmp_path / "mine.toml"
    script.write_bytes(b"# " + LATIN1 + b"\n")
    status, out = _run(["play", str(script), "--head", "human", "--emulate"], capsys)
    assert status == 2
    assert f"{script}: line 1: expected UTF-8 text, got byte 0xe2" in out


# --- a misspelt key -------------------------------------------------------------------------------------


def test_a_misspelt_key_names_the_nearest_and_itself(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = oh.write_mechanical(tmp_path / "m")
    text = (folder / "head.toml").read_text()
    (folder / "head.toml").write_text(text.replace("limits_deg", "limit_deg", 1))
    status, out = _run(["check", str(folder)], capsys)
    assert status == 2  # a profile that does not validate is bad input, as for every command
    assert "joint[0].limit_deg: expected one of the known keys" in out
    assert "(did you mean 'limits_deg'?), got 'limit_deg'" in out


# --- "of the rest" --------------------------------------------------------------------------------------


def test_of_the_rest_leaves_out_a_joint_no_servo_drives(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The builder took the eye-tilt servo out and left the joint in: sadness (AU1 AU4 AU15 AU17 AU41 AU54
    AU64) cannot show AU64 here, and the brows and lids it does show are all of the rest, not a third."""
    folder = oh.write_mechanical(tmp_path / "m")
    text = (folder / "head.toml").read_text()
    blocks = re.split(r"(?m)^(?=\[)", text)
    kept = [b for b in blocks if not (b.startswith("[[actuator]]") and re.search(r'(?m)^role = "eye_tilt"', b))]
    assert len(kept) == len(blocks) - 1
    (folder / "head.toml").write_text("".join(kept))
    assert main(["calibrate", "--head", str(folder), "--csv", str(write_template_csv(folder))]) == 0
    status, out = _run(["check", str(folder)], capsys)
    assert status == 0, out
    row = next(ln for ln in out.splitlines() if ln.strip().startswith("sadness"))
    assert "AU64" in row
    rest = re.search(r"\((\d+)% of the rest\)", row)
    assert rest is not None and int(rest.group(1)) >= 95, row


# --- `new` into a folder that holds the builder's own files ---------------------------------------------


@pytest.mark.parametrize("kind", ["mechanical", "human"])
def test_new_never_overwrites_the_builders_files_without_force(
    tmp_path: Path, kind: str, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "mine"
    (folder / "meshes").mkdir(parents=True)
    (folder / "meshes" / "jaw.stl").write_text("my CAD export")
    (folder / "calibration_template.csv").write_text("role,target,tick\njaw,0,2000\njaw,20,2300\n")
    status, out = _run(["new", str(folder), "--from", kind], capsys)
    assert status == 2
    assert f"would overwrite {folder / 'calibration_template.csv'}" in out and "--force" in out
    assert (folder / "calibration_template.csv").read_text().endswith("jaw,20,2300\n")
    assert (folder / "meshes" / "jaw.stl").read_text() == "my CAD export"
    assert not (folder / "head.toml").exists()
    assert main(["new", str(folder), "--from", kind, "--force"]) == 0
    assert (folder / "head.toml").is_file()


def test_new_refuses_an_empty_folder_name(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)  # `servoface new $DIR` with DIR unset: not the current folder
    with pytest.raises(SystemExit) as exc:
        main(["new", ""])
    assert exc.value.code == 2
    assert "argument folder: expected the name of the profile folder to create" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


# --- `calibrate --roles` / `--mirror` with the whole measurement file -----------------------------------


def test_calibrate_roles_takes_its_rows_from_the_whole_template(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """What `check` prints for a servo swapped for another model (`calibrate --roles jaw`, or `--csv` the
    template) works on the template as `new` wrote it: the other servos' rows are passed over, not refused
    as an "unknown role"."""
    folder = _calibrated_mechanical(tmp_path / "m")
    before = (folder / "calibration.json").read_text()
    template = folder / "calibration_template.csv"
    text = template.read_text().replace("jaw,22,2298", "jaw,22,2300")  # the jaw re-measured
    assert text != template.read_text()
    template.write_text(text)
    status, out = _run(["calibrate", "--head", str(folder), "--roles", "jaw", "--csv", str(template)], capsys)
    assert status == 0, out
    assert "unknown role" not in out
    assert (folder / "calibration.json").read_text() != before
    status, out = _run(
        ["calibrate", "--head", str(folder), "--mirror", "brow_l:brow_r", "--csv", str(template)], capsys
    )
    assert status == 0, out
    assert main(["check", str(folder), "--no-report"]) == 0


# --- a direct table that names servos the builder took out ----------------------------------------------


def test_every_direct_row_names_the_servo_the_head_lacks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The brows' servos taken out, direct.toml left as it was: AU1, AU2 and AU4 all name the missing
    actuators (AU2 and AU4 said "its direct table row has no targets", which they have)."""
    folder = oh.write_mechanical(tmp_path / "m")
    blocks = re.split(r"(?m)^(?=\[)", (folder / "head.toml").read_text())
    kept = [b for b in blocks if not (b.startswith("[[actuator]]") and re.search(r'(?m)^role = "brow_', b))]
    assert len(kept) == len(blocks) - 2
    (folder / "head.toml").write_text("".join(kept))
    status, out = _run(["check", str(folder)], capsys)
    assert status == 1  # no calibration yet
    for au in ("AU1", "AU2", "AU4"):
        row = next(ln for ln in out.splitlines() if ln.strip().startswith(f"{au} ") and "reaches nothing" in ln)
        assert "actuator 'brow_l' is not in the head; actuator 'brow_r' is not in the head" in row, row
    assert "has no targets" not in out


def test_preview_names_the_nearest_expression(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """As `play` does (the README: a misspelt name gets the nearest one)."""
    folder = oh.write_mechanical(tmp_path / "m")
    status, out = _run(["preview", "happyness", "--head", str(folder), "-o", str(tmp_path / "x.png")], capsys)
    assert status == 2
    assert "unknown expression 'happyness' (did you mean 'happiness'?)" in out
    assert not (tmp_path / "x.png").exists()


def _with_first_model(folder: Path, model: str) -> None:
    text = (folder / "head.toml").read_text()
    first = re.search(r'model = "[^"]+"', text)
    assert first is not None
    (folder / "head.toml").write_text(text[: first.start()] + f'model = "{model}"' + text[first.end() :])


def test_a_model_spelt_as_scan_prints_it_is_accepted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`servoface scan` and `servoface emulate` print "MX-28(2.0)"; a builder copies that into head.toml."""
    from servoface.sim.heads import load_head

    folder = oh.write_mechanical(tmp_path / "m")
    _with_first_model(folder, "MX-28(2.0)")
    assert load_head(folder).actuators[0].servo.model == "MX-28"
    assert main(["calibrate", "--head", str(folder), "--csv", str(write_template_csv(folder))]) == 0
    status, out = _run(["check", str(folder), "--no-report"], capsys)
    assert status == 0, out


@pytest.mark.parametrize(
    ("typed", "hint"), [("xl330-m288", "XL330-M288"), ("XL330-M28", "XL330-M288"), ("XM430-W210", None)]
)
def test_a_misspelt_model_names_the_nearest_only_when_close(
    tmp_path: Path, typed: str, hint: str | None, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = oh.write_mechanical(tmp_path / "m")
    _with_first_model(folder, typed)
    status, out = _run(["check", str(folder)], capsys)
    assert status == 2
    assert "actuator[0].servo.model: expected one of the known servo models" in out
    assert f"got '{typed}'" in out
    if hint is None:  # another servo (other gearing), not a typo of one
        assert "did you mean" not in out
    else:
        assert f"(did you mean '{hint}'?)" in out


# --- play before calibrate ------------------------------------------------------------------------------


def test_play_before_calibrating_names_the_next_step(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """README: each command names the next when something is missing (was: "cannot read the calibration
    file (No such file or directory)")."""
    folder = oh.write_mechanical(tmp_path / "m")
    status, out = _run(["play", "happiness", "--head", str(folder), "--emulate"], capsys)
    assert status == 2
    assert f"has no calibration file {folder / 'calibration.json'} yet" in out
    assert f"servoface calibrate --head {folder} --port" in out
    assert f"--csv {folder / 'calibration_template.csv'}" in out


def test_a_direct_row_for_an_au_no_table_has_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """[AU99] (a typo for AU9) was dropped without a word: the AU moved nothing and `check` said ok."""
    folder = _calibrated_mechanical(tmp_path / "m")
    with (folder / "direct.toml").open("a") as fh:
        fh.write('\n[AU99]\ntargets = { "jaw" = 5.0 }\n')
    status, out = _run(["check", str(folder)], capsys)
    assert status == 1
    assert "direct.toml: AU99: expected an AU of the human AU table (AU1, AU2, AU4," in out
    assert "got AU99" in out
