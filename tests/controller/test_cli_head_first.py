"""What play, say and node will show is solved on the head's own face model before anything is opened or
started: an expression the head's AU table refuses (AU12 limited to 0.5), a library of another face type or
a broken direct table is refused in one line naming the expression, file and AU, exit 2 — no "# opening
head" line, no speech synthesised, no Zenoh session (it used to be found with torque on, or after the
session was up)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from servoface.controller.cli import main

from tests.human_copy import human_copy, narrow_au_copy

ROOT = Path(__file__).resolve().parents[2]


class Opened(Exception):  # noqa: N818 - what the tests raise where a refused input must not reach
    """Raised in place of opening the head or starting the session: the refusal came too late."""


@pytest.fixture(scope="module")
def unshowable(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, str]]:
    """Profiles that load, whose expressions fail only on the head's own face model; each with the words
    its refusal must carry."""
    base = tmp_path_factory.mktemp("unshowable")
    narrow = narrow_au_copy(base / "narrow_au")
    dog_library = human_copy(base / "dog_library", name='"dog_library"', expressions='"expr.toml"')
    (dog_library / "expr.toml").write_text((ROOT / "sim" / "expressions" / "dog.toml").read_text())
    direct = human_copy(base / "bad_direct", name='"bad_direct"', au_direct='"direct.toml"')
    (direct / "direct.toml").write_text('schema_version = 1\nface_type = "human"\n[AU12]\ntargets = = 1\n')
    library = ROOT / "sim" / "expressions" / "human.toml"
    return {
        "narrow_au": (
            narrow,
            f"expression 'happiness' in {library}, on head 'narrow_au': AU12: expected a finite intensity in "
            "[0.0, 0.5], got 1.0",
        ),
        "dog_library": (dog_library, f"the expression library in {dog_library / 'expr.toml'} is for a dog face"),
        "bad_direct": (direct, "direct.toml: not valid TOML"),
    }


@pytest.fixture
def never_opened(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Opening a head (play, say) raises `Opened`; the list records who tried."""
    from servoface.controller.cli import play, say

    tried: list[str] = []

    def refuse(*args: Any, **kwargs: Any) -> Any:
        tried.append("open_face")
        raise Opened("the head was opened for an input that should have been refused")

    monkeypatch.setattr(play, "open_face", refuse)
    monkeypatch.setattr(say, "open_face", refuse)
    return tried


def _refused_in_one_line(status: int, out: str, err: str, command: str, expected: str) -> None:
    assert status == 2, out + err
    assert out == "", out
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # no "# opening head ..." before it
    assert lines[0].startswith(f"servoface {command}: ") and expected in lines[0], lines[0]


# --- play ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["narrow_au", "dog_library", "bad_direct"])
def test_play_solves_the_expression_on_the_head_before_opening(
    kind: str,
    unshowable: dict[str, tuple[Path, str]],
    never_opened: list[str],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`play happiness --head narrow_au --emulate` used to open the head, switch torque on, and then wait
    on a command the service could not solve (frames dropped as faults) until Ctrl-C."""
    folder, expected = unshowable[kind]
    status = main(["play", "happiness", "--head", str(folder), "--emulate"])
    out, err = capsys.readouterr()
    _refused_in_one_line(status, out, err, "play", expected)
    assert never_opened == []


def _script(folder: Path, body: str, end_s: float = 1.0) -> Path:
    path = folder / "s.toml"
    path.write_text(f'[script]\nface = "human"\nend_s = {end_s}\n' + body)
    return path


@pytest.mark.parametrize(
    "body, clip",
    [
        ('[[play]]\nat_s = 0.0\nlibrary = "happiness"\n', "happiness"),
        (
            "[poses]\nbeam = { AU12 = 0.8 }\n"
            '[expressions.beam]\nduration_s = 0.5\nmovements = [{ pose = "beam", percent = 100 }]\n'
            '[[play]]\nat_s = 0.2\ntrack = "gesture"\nsequence = ["beam"]\n',
            "beam",
        ),
    ],
    ids=["library", "own_expression"],
)
def test_play_solves_every_expression_of_a_script_on_the_head_before_opening(
    body: str,
    clip: str,
    unshowable: dict[str, tuple[Path, str]],
    never_opened: list[str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    folder, _ = unshowable["narrow_au"]
    script = _script(tmp_path, body)
    status = main(["play", str(script), "--head", str(folder), "--emulate"])
    out, err = capsys.readouterr()
    value = "1.0" if clip == "happiness" else "0.8"
    expected = f"{script}: expression {clip!r}"
    _refused_in_one_line(status, out, err, "play", expected)
    assert f", on head 'narrow_au': AU12: expected a finite intensity in [0.0, 0.5], got {value}" in err
    assert never_opened == []


def test_play_of_a_script_within_the_heads_range_still_plays(
    unshowable: dict[str, tuple[Path, str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder, _ = unshowable["narrow_au"]
    body = (
        "[poses]\nsmile = { AU12 = 0.5, AU6 = 0.3 }\n"
        '[expressions.smile]\nduration_s = 0.2\nmovements = [{ pose = "smile", percent = 100 }]\n'
        '[[play]]\nat_s = 0.0\nexpression = "smile"\n'
    )
    script = _script(tmp_path, body, end_s=0.3)
    status = main(["play", str(script), "--head", str(folder), "--emulate"])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    assert "frames" in out


# --- say ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["narrow_au", "dog_library", "bad_direct"])
def test_say_solves_its_expression_on_the_head_before_speaking_or_opening(
    kind: str,
    unshowable: dict[str, tuple[Path, str]],
    never_opened: list[str],
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from servoface.controller.speech import lipsync

    def no_speech(*args: Any, **kwargs: Any) -> Any:
        raise Opened("espeak-ng was run for an input that should have been refused")

    monkeypatch.setattr(lipsync, "speech_from_text", no_speech)
    folder, expected = unshowable[kind]
    out_dir = tmp_path / "speech"
    argv = ["say", "hello", "--expression", "happiness", "--head", str(folder), "--emulate", "--out", str(out_dir)]
    status = main(argv)
    out, err = capsys.readouterr()
    _refused_in_one_line(status, out, err, "say", expected)
    assert never_opened == [] and not out_dir.exists()


# --- node ---------------------------------------------------------------------------------------------------


@pytest.fixture
def sessions(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Starting the node's Zenoh session raises `Opened`; the list records each attempt."""
    from servoface.controller.cli import node

    started: list[str] = []

    def refuse(*args: Any, **kwargs: Any) -> Any:
        started.append("session")
        raise Opened("the Zenoh session was started")

    monkeypatch.setattr(node, "open_from_args", refuse)
    return started


def _broken_profiles(base: Path, unshowable: dict[str, tuple[Path, str]]) -> dict[str, tuple[Path, str]]:
    toml = human_copy(base / "bad_toml", name='"bad_toml"')
    (toml / "head.toml").write_text((toml / "head.toml").read_text() + "\nname = = 1\n")
    uncalibrated = human_copy(base / "uncalibrated", name='"uncalibrated"')
    (uncalibrated / "calibration.json").write_text('{"schema_version": 1, "servos": \n')
    return {
        **unshowable,
        "bad_toml": (toml, f"{toml / 'head.toml'}: not valid TOML"),
        "uncalibrated": (uncalibrated, f"{uncalibrated / 'calibration.json'}: not valid JSON"),
    }


def test_node_warns_of_an_expression_the_head_cannot_show_and_starts(
    unshowable: dict[str, tuple[Path, str]], sessions: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """A head whose AU table narrows AU12 still serves every other expression: the node starts, after one
    warning line naming the expression it cannot show (a peer asking for it is refused by `express`)."""
    folder, expected = unshowable["narrow_au"]
    with pytest.raises(Opened):
        main(["node", "--name", "ada", "--head", str(folder), "--emulate"])
    assert sessions == ["session"]
    out, err = capsys.readouterr()
    assert out == "", out
    assert err.startswith("servoface node: warning: ") and expected in err, err
    assert all(line.startswith("servoface node: warning: ") for line in err.splitlines()), err


@pytest.mark.parametrize("kind", ["bad_toml", "uncalibrated", "dog_library", "bad_direct"])
def test_node_refuses_a_broken_profile_before_its_session_starts(
    kind: str,
    unshowable: dict[str, tuple[Path, str]],
    sessions: list[str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    folder, expected = _broken_profiles(tmp_path, unshowable)[kind]
    status = main(["node", "--name", "ada", "--head", str(folder), "--emulate"])
    out, err = capsys.readouterr()
    _refused_in_one_line(status, out, err, "node", expected)
    assert "listening" not in out + err and sessions == []


@pytest.mark.parametrize("head", ["human", "dog"])
def test_node_starts_its_session_for_a_good_head(
    head: str, sessions: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """The built-in heads pass the check (every expression of their library solves): the session is next."""
    with pytest.raises(Opened):
        main(["node", "--name", "ada", "--head", head, "--emulate"])
    assert sessions == ["session"]
    out, err = capsys.readouterr()
    assert out == "" and err == "", out + err
