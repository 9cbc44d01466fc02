"""`--calibration FILE` is read and checked against the head before anything is opened, announced or
written: a missing file, malformed JSON or another head's calibration gives one line naming the file and
exit 2 — no "# opening head" line, no speech files, no --record file truncated, no bound port."""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import pytest
from servoface.calibration import CalibrationError
from servoface.controller.cli import main
from servoface.controller.cli.head_args import checked_calibration
from servoface.sim.heads import load_head

ROOT = Path(__file__).resolve().parents[2]
HUMAN = ROOT / "sim" / "heads" / "human"
DOG_CALIBRATION = ROOT / "sim" / "heads" / "dog" / "calibration.json"


def _bad_calibration(kind: str, folder: Path) -> tuple[Path, str]:
    """A calibration file of the ``kind`` asked for, and what the refusal must say about it."""
    if kind == "missing":
        return folder / "nosuch.json", "cannot read the calibration file"
    if kind == "malformed":
        path = folder / "broken.json"
        path.write_text('{"schema_version": 1, "servos": \n')
        return path, "not valid JSON"
    return DOG_CALIBRATION, "no servo for role(s) brow_inner_l"  # the dog's, for the human head


def _refused_alone(status: int, out: str, err: str, path: Path, expected: str) -> None:
    assert status == 2, out + err
    assert out == "", out  # nothing announced or reported (a recording's summary, "wrote ...")
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # the refusal is the only line: no "# opening head ..." before it
    assert str(path) in lines[0] and expected in lines[0], lines[0]
    assert "Traceback" not in err


KINDS = ["missing", "malformed", "other_head"]


@pytest.mark.parametrize("kind", KINDS)
def test_play_refuses_the_calibration_before_opening(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, expected = _bad_calibration(kind, tmp_path)
    status = main(["play", "happiness", "--emulate", "--calibration", str(path)])
    out, err = capsys.readouterr()
    _refused_alone(status, out, err, path, expected)


def test_play_input_refuses_the_calibration_before_reading_the_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, expected = _bad_calibration("malformed", tmp_path)
    status = main(["play", "--input", "sample:openface_smile", "--emulate", "--calibration", str(path)])
    out, err = capsys.readouterr()
    _refused_alone(status, out, err, path, expected)  # (the recording's summary used to come first)


@pytest.mark.parametrize("kind", KINDS)
def test_say_refuses_the_calibration_before_speaking_or_writing(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, expected = _bad_calibration(kind, tmp_path)
    out_dir = tmp_path / "speech"
    status = main(["say", "hello", "--emulate", "--calibration", str(path), "--out", str(out_dir)])
    out, err = capsys.readouterr()
    _refused_alone(status, out, err, path, expected)
    assert not out_dir.exists()  # no speech.wav / speech.toml written for a run that never starts


@pytest.mark.parametrize("kind", KINDS)
def test_stream_refuses_the_calibration_before_binding_or_recording(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, expected = _bad_calibration(kind, tmp_path)
    record = tmp_path / "earlier.jsonl"
    record.write_text('{"t": 0.0, "aus": {"AU12": 0.5}}\n')  # an earlier recording at the --record path
    argv = ["stream", "--emulate", "--udp", "127.0.0.1:0", "--calibration", str(path), "--record", str(record)]
    status = main(argv)
    out, err = capsys.readouterr()
    _refused_alone(status, out, err, path, expected)
    assert record.read_text() == '{"t": 0.0, "aus": {"AU12": 0.5}}\n'  # not truncated


def test_studio_refuses_the_calibration_before_serving(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, expected = _bad_calibration("other_head", tmp_path)
    argv = ["studio", "--head", "human", "--emulate", "--calibration", str(path), "--no-render", "--port-http", "0"]
    status = main(argv)
    out, err = capsys.readouterr()
    assert status == 2 and out == "" and len(err.strip().splitlines()) == 1, out + err
    assert "brow_inner_l" in err


# --- checked_calibration itself ---------------------------------------------------------------------------


def _args(head: str, calibration: Path | None) -> argparse.Namespace:
    return argparse.Namespace(head=head, calibration=calibration)


def test_checked_calibration_takes_a_copy_of_the_head_under_another_name(tmp_path: Path) -> None:
    """A profile copied from the human head keeps the human's calibration (its ``head`` says 'human'):
    the roles and ids are what count, not the name."""
    folder = tmp_path / "my_human"
    shutil.copytree(HUMAN, folder)
    toml = folder / "head.toml"
    toml.write_text(toml.read_text().replace('name = "human"', 'name = "my_human"', 1))
    head = load_head(folder)
    cal = checked_calibration(_args(str(folder), None), head)
    assert cal.head == "human" and set(cal.roles) == set(head.roles)
    assert checked_calibration(_args(str(folder), HUMAN / "calibration.json"), head).roles == cal.roles


def test_checked_calibration_names_another_heads_file(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError) as info:
        checked_calibration(_args("human", DOG_CALIBRATION), load_head("human"))
    text = str(info.value)
    assert text.startswith(f"{DOG_CALIBRATION}: servos: no servo for role(s) brow_inner_l, ")
    assert "more of head 'human' (it is a calibration of head 'dog')" in text
    assert f"`servoface check human --calibration {DOG_CALIBRATION}`" in text


def test_checked_calibration_names_servo_ids_that_differ(tmp_path: Path) -> None:
    data = json.loads((HUMAN / "calibration.json").read_text())
    ids = [s["id"] for s in data["servos"]]
    data["servos"][0]["id"], data["servos"][1]["id"] = ids[1], ids[0]  # two servos swapped
    path = tmp_path / "swapped.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationError) as info:
        checked_calibration(_args("human", path), load_head("human"))
    first, second = data["servos"][0]["role"], data["servos"][1]["role"]
    assert f"{first} {ids[0]} -> {ids[1]}, {second} {ids[1]} -> {ids[0]}" in str(info.value)
    assert str(info.value).startswith(f"{path}: servos: servo ids differ from the profile of head 'human'")


def test_checked_calibration_of_an_uncalibrated_profile_says_how_to_calibrate(tmp_path: Path) -> None:
    from servoface.controller.errors import ControllerError

    folder = tmp_path / "fresh"
    assert main(["new", str(folder), "--from", "mechanical"]) == 0
    with pytest.raises(ControllerError, match="has no calibration file .* yet: run `servoface calibrate"):
        checked_calibration(_args(str(folder), None), load_head(folder))
