"""`servoface calibrate`: CSV mode end to end, the interactive mode on an in-process emulator with typed
keys, and regenerating a built-in file."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from servoface.calibration.fileformat import load_calibration
from servoface.controller.cli import main


def test_csv_mode_through_the_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = ["role,target,tick"]
    for t in (0.0, 5.0, 12.5, 20.0, 25.0):
        rows.append(f"jaw,{t},{round(2048 + t * 4096 / 360)}")
    for t, tick in ((-4.0, 1700), (0.0, 2048), (4.0, 2420), (8.0, 2650), (13.5, 2850)):
        rows.append(f"lip_corner_l,{t},{tick}")
    (tmp_path / "m.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "human.json"
    code = main(
        [
            "calibrate",
            "--head",
            "human",
            "--csv",
            str(tmp_path / "m.csv"),
            "--roles",
            "jaw,lip_corner_l",
            "--out",
            str(out),
            "--plot-dir",
            str(tmp_path / "plots"),
        ]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    assert "saved" in text and "EEPROM backstop" in text
    cal = load_calibration(out)
    assert len(cal) == 30  # the other servos are kept from the head's calibration file
    assert cal["lip_corner_l"].to_tick(4.0) == 2420 and cal["lip_corner_l"].curve.kind == "pchip"
    assert cal["jaw"].curve.kind == "linear"
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == ["jaw.png", "lip_corner_l.png"]
    assert text.rstrip().splitlines()[-1] == f"next: servoface check human --calibration {out}"  # the file written


def test_cli_reports_bad_csv_with_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "m.csv").write_text("jaw,0,2048\njaw,25,two\n")
    code = main(["calibrate", "--head", "human", "--csv", str(tmp_path / "m.csv"), "--out", str(tmp_path / "x")])
    assert code == 2  # a malformed measurement file is bad input
    assert "line 2: tick 'two' is not an integer" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    "body, message",
    [
        ("jaw,0,2048\njaw,25,2332\njaw,-1e9,1593\n", "line 3: servo 'jaw': measured target -1e+09 deg is far outside"),
        ("jaw,-25,2047\njaw,50,2049\n", "whole range 0..25 deg maps to one tick (2048)"),
    ],
)
def test_cli_measurements_that_cannot_make_a_curve_are_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, message: str
) -> None:
    """A measurement file whose numbers cannot be fit is the user's input to fix (exit 2), with the cause:
    a target far outside the servo's range (a typo) named by its line; ticks that do not follow the target."""
    (tmp_path / "m.csv").write_text(body)
    out = tmp_path / "x.json"
    code = main(["calibrate", "--head", "human", "--csv", str(tmp_path / "m.csv"), "--roles", "jaw", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err
    assert "must satisfy" not in err
    assert not out.exists()


@pytest.fixture
def typed_keys(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """Feed input() from a list; each key waits a little so the emulated servo finishes a jog."""
    keys: list[str] = []

    def fake_input(prompt: str = "") -> str:
        time.sleep(0.15)
        if not keys:
            raise EOFError
        return keys.pop(0)

    monkeypatch.setattr("builtins.input", fake_input)
    yield keys


def test_interactive_cli_on_the_in_process_emulator(
    tmp_path: Path, typed_keys: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    up = round(25 * 4096 / 360)  # jaw: 0 deg at 2048 (neutral = lower), 25 deg 284 ticks up
    # capture neutral; g = go where the shipped calibration puts 25 deg; capture; then a free point:
    # jog 142 ticks back, type its angle; ? = help; d = done
    typed_keys += ["", "g", "", "-142", "?", f"={142 * 360 / 4096}", "d"]
    out = tmp_path / "jaw.json"
    code = main(
        [
            "calibrate",
            "--head",
            "human",
            "--emulate",
            "--roles",
            "jaw",
            "--points",
            "0",
            "--free-points",
            "--out",
            str(out),
        ]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    jaw = load_calibration(out)["jaw"]
    assert (jaw.min_tick, jaw.max_tick) == (2048, 2048 + up)
    assert jaw.to_tick(12.5) == 2048 + round(12.5 * 4096 / 360)
    assert sorted(jaw.measured_points[:, 1].tolist()) == [2048, 2048 + 142, 2048 + up]
    assert "keys:" in text


def test_abort_saves_nothing(tmp_path: Path, typed_keys: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    typed_keys += ["q"]
    code = main(["calibrate", "--head", "human", "--emulate", "--roles", "jaw", "--out", str(tmp_path / "x.json")])
    assert code == 1
    assert "nothing saved" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_builtin_regeneration(tmp_path: Path) -> None:
    out = tmp_path / "dog.json"
    assert main(["calibrate", "--head", "dog", "--builtin", "--out", str(out)]) == 0
    shipped = Path(__file__).resolve().parents[2] / "sim" / "heads" / "dog" / "calibration.json"
    assert out.read_text() == shipped.read_text()


def test_port_mode_checks_every_servo_answers_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Over a pty (as with 'servoface emulate'): a missing id and a wrong model stop before any write."""
    from servoface.hardware.emulator import ServoChain

    with ServoChain.create(ids=[(18, "XL330-M288"), (20, "XM430-W350")], wire_time=False) as chain:
        port = chain.serve_pty()
        code = main(
            [
                "calibrate",
                "--head",
                "human",
                "--port",
                port,
                "--roles",
                "jaw,neck_pan,neck_tilt",
                "--out",
                str(tmp_path / "x.json"),
            ]
        )
        err = capsys.readouterr().err
        assert code == 1
        assert "no answer from id(s) 19 (neck_pan)" in err
        assert "18 (jaw) is a XL330-M288, not a XL430-W250" in err
        assert "nothing saved" in err and not (tmp_path / "x.json").exists()
        assert chain.goal_writes() == [] and not chain.servo(20).torque_on


def test_mirror_derives_the_right_side_from_the_left(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = [f"brow_inner_l,{t},{tick}" for t, tick in ((-5.0, 1700), (0.0, 2048), (3.0, 2260), (8.0, 2610))]
    (tmp_path / "m.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "h.json"
    code = main(
        [
            "calibrate",
            "--head",
            "human",
            "--csv",
            str(tmp_path / "m.csv"),
            "--roles",
            "brow_inner_l,brow_inner_r",
            "--mirror",
            "brow_inner_l:brow_inner_r",
            "--out",
            str(out),
        ]
    )
    assert code == 0, capsys.readouterr().err
    cal = load_calibration(out)
    assert cal.roles[:2] == ("brow_inner_l", "brow_inner_r")
    assert cal["brow_inner_r"].to_tick(3.0) == 2048 - 212 and cal["brow_inner_r"].servo_id == 2
    assert main(["calibrate", "--head", "human", "--builtin", "--mirror", "jaw:jaw", "--out", str(out)]) == 2
    assert "two different roles" in capsys.readouterr().err
