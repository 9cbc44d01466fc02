"""`servoface check` on a builder's mistakes: each is found and named with the fix, and no malformed profile,
AU table or direct table makes any command print a traceback."""

from __future__ import annotations

import json
import random
import re
from pathlib import Path

import pytest
from servoface.controller.cli import main
from servoface.controller.new_head import write_template_csv

from tests.integration import own_heads as oh


def _calibrated_dog(folder: Path, *, scale: bool = True) -> Path:
    oh.write_dog_in_metres(folder, scale=scale)
    assert main(["calibrate", "--head", str(folder), "--csv", str(write_template_csv(folder))]) == 0
    return folder


def test_a_calibration_whose_servo_model_differs_is_a_problem(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _calibrated_dog(tmp_path / "dog")
    data = json.loads((folder / "calibration.json").read_text())
    servos = data["servos"]
    first = servos[next(iter(servos))] if isinstance(servos, dict) else servos[0]
    first["model"] = "XL330-M288"  # the profile says XL430-W250 for the jaw
    (folder / "calibration.json").write_text(json.dumps(data))
    capsys.readouterr()
    assert main(["check", str(folder), "--no-report"]) == 1
    out = capsys.readouterr().out
    assert "jaw: servo model XL430-W250 in head.toml but XL330-M288 in the calibration" in out
    assert f"servoface calibrate --head {folder} --roles jaw" in out


def _with_jaw_model(folder: Path, model: str) -> Path:
    data = json.loads((folder / "calibration.json").read_text())
    servos = data["servos"]
    first = servos[next(iter(servos))] if isinstance(servos, dict) else servos[0]
    first["model"] = model
    (folder / "calibration.json").write_text(json.dumps(data))
    return folder


def test_play_refuses_a_calibration_measured_on_another_servo_model_before_opening(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _with_jaw_model(_calibrated_dog(tmp_path / "dog"), "XL330-M288")  # the profile: XL430-W250
    capsys.readouterr()
    assert main(["play", "happiness", "--head", str(folder), "--emulate"]) == 2
    out, err = capsys.readouterr()
    assert "servo models differ from the profile of head '" in err
    assert "(role: profile -> file: jaw XL430-W250 -> XL330-M288)" in err
    assert f"servoface check {folder}" in err  # where every difference is listed
    assert "opening" not in out and "torque" not in out


def test_opening_a_head_refuses_a_calibration_of_another_servo_model(tmp_path: Path) -> None:
    from servoface.calibration import load_calibration
    from servoface.controller.face import Face
    from servoface.controller.head_servos import calibration_mismatches
    from servoface.sim.errors import HeadProfileError
    from servoface.sim.heads import load_head

    folder = _with_jaw_model(_calibrated_dog(tmp_path / "dog"), "XL330-M288")
    head = load_head(folder)
    found = calibration_mismatches(head, load_calibration(folder / "calibration.json"))
    assert [(m.kind, m.role, m.profile, m.calibration) for m in found] == [("model", "jaw", "XL430-W250", "XL330-M288")]
    with pytest.raises(HeadProfileError, match=r"role 'jaw' is servo model XL430-W250 in the profile but XL330-M288"):
        Face.open(head, emulate=True)


def test_a_model_written_by_its_catalogue_alias_is_the_same_model(tmp_path: Path) -> None:
    from servoface.controller.head_servos import same_model

    assert same_model("MX-28", "MX-28(2.0)") and same_model("mx-28", "MX-28-2.0")
    assert not same_model("XL330-M288", "XL330-M077")
    assert same_model("my-servo", "my-servo") and not same_model("my-servo", "other")  # unknown: as written


def test_a_role_the_calibration_lacks_names_the_command_that_adds_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _calibrated_dog(tmp_path / "dog")
    text = (folder / "head.toml").read_text()
    text += '\n[[joint]]\nname = "tail"\npivot_mm = [0.0, 60.0, -80.0]\naxis = [0.0, 1.0, 0.0]\n'
    text += "limits_deg = [-30.0, 30.0]\n"
    text += '\n[[actuator]]\nrole = "tail"\nservo = { id = 9, model = "XL330-M288" }\nkind = "joint"\n'
    (folder / "head.toml").write_text(text)
    capsys.readouterr()
    assert main(["check", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "calibration has no servo for role 'tail'" in out
    assert f"servoface calibrate --head {folder} --roles tail" in out


@pytest.mark.parametrize("scale", ["0", "-1000", "0.0"])
def test_a_scale_that_is_not_positive_is_refused(
    tmp_path: Path, scale: str, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = oh.write_dog_in_metres(tmp_path / "dog")
    text = (folder / "head.toml").read_text().replace("scale = 1000.0", f"scale = {scale}", 1)
    (folder / "head.toml").write_text(text)
    assert main(["check", str(folder)]) == 2  # a profile that does not validate: bad input
    err = capsys.readouterr().err
    assert "part[0].scale: expected a positive factor to millimetres" in err and "Traceback" not in err


def test_a_mesh_in_metres_without_scale_is_warned_with_its_size(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _calibrated_dog(tmp_path / "dog", scale=False)
    capsys.readouterr()
    main(["check", str(folder), "--no-report"])
    out = capsys.readouterr().out
    assert re.search(r"warning: part\[0\] 'skull' is 0\.\d+ mm across: a mesh in metres\? set scale = 1000", out), out
    assert re.search(r"warning: the head is 0\.\d+ mm across \(expected 40\.\.1500 mm\)", out), out


# ------------------------------------------------------------------------------------------------------
# fuzz: a mechanical head whose parts do not collide (no collision tables to build), mutated line by line


def _mutants(text: str, n: int, seed: int) -> list[str]:
    rng = random.Random(seed)
    lines = text.splitlines()
    numbers = re.compile(r"-?\d+(\.\d+)?")
    replacements = ["0", "-1000", "1e309", '"x"', "[]", "nan", "true", "-0.0", "99999", "{}"]
    out = []
    for _ in range(n):
        ls = list(lines)
        op = rng.randrange(5)
        i = rng.randrange(len(ls))
        if op == 0:
            del ls[i]
        elif op == 1 and numbers.search(ls[i]):
            ls[i] = numbers.sub(lambda _m: rng.choice(replacements), ls[i], count=1)
        elif op == 2 and '"' in ls[i]:
            ls[i] = re.sub(r'"[^"]*"', rng.choice(['""', '"nope"', '"builtin:none"', '"../../etc"']), ls[i], count=1)
        elif op == 3:
            ls.insert(i, rng.choice(["[[actuator]]", "[[joint]]", "[skin]", "[[muscle]]", "[anchors]", "x = 1"]))
        else:
            ls = ls[:i]
        out.append("\n".join(ls) + "\n")
    return out


FUZZ_BASE = oh.MECH_TOML.replace('mesh = "stl/', 'collides = false\nmesh = "stl/')


@pytest.mark.parametrize("seed", range(3))
def test_no_traceback_from_malformed_profiles(tmp_path: Path, seed: int, capsys: pytest.CaptureFixture[str]) -> None:
    folder = oh.write_mechanical(tmp_path / "fuzz")
    (folder / "head.toml").write_text(FUZZ_BASE)
    assert main(["calibrate", "--head", str(folder), "--csv", str(write_template_csv(folder))]) == 0
    direct = (folder / "direct.toml").read_text()
    for k, mutant in enumerate(_mutants(FUZZ_BASE, 20, seed)):
        (folder / "head.toml").write_text(mutant)
        if k % 3 == 0:  # and the direct table too, now and then
            (folder / "direct.toml").write_text(_mutants(direct, 1, seed * 100 + k)[0])
        else:
            (folder / "direct.toml").write_text(direct)
        capsys.readouterr()
        try:
            status = main(["check", str(folder)])
        except Exception as err:  # noqa: BLE001 - the point of the test
            pytest.fail(f"servoface check raised {type(err).__name__}: {err}\n--- head.toml ---\n{mutant}")
        out, err = capsys.readouterr()
        assert status in (0, 1, 2), out + err  # 2: the mutant does not load; 1: problems in one that does
        assert (status == 2) == ("next: fix the profile" in err), out + err
        assert "Traceback" not in out + err
        if status == 0 and k % 4 == 0:
            png = tmp_path / "p.png"
            assert main(["preview", "surprise", "--head", str(folder), "-o", str(png), "--size", "160x120"]) in (0, 1)


def test_no_traceback_from_malformed_skin_profiles_and_au_tables(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = oh.write_skin(tmp_path / "skin")
    assert main(["calibrate", "--head", str(folder), "--csv", str(write_template_csv(folder))]) == 0
    cases = [(m, oh.SKIN_AUS) for m in _mutants(oh.SKIN_TOML, 6, 7)]
    cases += [(oh.SKIN_TOML, a) for a in _mutants(oh.SKIN_AUS, 6, 8)]
    for head_text, aus_text in cases:
        (folder / "head.toml").write_text(head_text)
        (folder / "aus.toml").write_text(aus_text)
        capsys.readouterr()
        for argv in (["check", str(folder)], ["play", "surprise", "--head", str(folder), "--emulate", "--hold", "0.1"]):
            try:
                status = main(argv)
            except Exception as err:  # noqa: BLE001 - the point of the test
                pytest.fail(f"servoface {argv[0]} raised {type(err).__name__}: {err}\n{head_text}\n{aus_text}")
            out, err = capsys.readouterr()
            assert status in (0, 1, 2) and "Traceback" not in out + err, out + err
