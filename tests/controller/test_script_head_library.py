"""A script's ``library = "name"`` entries name expressions of the head's own library (its profile's
``expressions`` file) as well as the face type's built-in one: a head with an expression of its own plays it
from a script (`servoface play`, `Face.play`, the head service), and a shipped script's built-in names still
play on that head. Before, only the built-in library was searched: a head's own expression was "not in the
human library"."""

from __future__ import annotations

from pathlib import Path

import pytest
from servoface.controller.cli import main
from servoface.controller.script import ScriptError, load_script

from tests.human_copy import human_copy

WINK = """schema_version = 1
face_type = "human"

[neutral]
source = "[test] the rest face"
aus = {}

[half_smile]
source = "[test] a head's own expression"
aus = { AU12 = 0.4, AU6 = 0.2 }
"""
SCRIPT = '[script]\nface = "human"\n\n[[play]]\nat_s = 0.0\nlibrary = "{name}"\n'


@pytest.fixture(scope="module")
def own(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built-in human profile with an expression library of its own (no 'happiness' in it)."""
    folder = tmp_path_factory.mktemp("own") / "own_lib"
    human_copy(folder, name='"own_lib"', expressions='"lib.toml"')
    (folder / "lib.toml").write_text(WINK)
    for name in ("half_smile", "happiness", "glee"):
        (folder / f"{name}.toml").write_text(SCRIPT.format(name=name))
    return folder


def test_a_script_names_the_heads_own_expression_and_the_built_in_ones(own: Path) -> None:
    lib = own / "lib.toml"
    script = load_script(own / "half_smile.toml", library=lib)
    assert script.sample(1.0).aus["AU12"] == pytest.approx(0.4, abs=0.05)  # at its apex
    assert load_script(own / "happiness.toml", library=lib).sample(1.0).aus["AU12"] > 0.9  # built-in, as before
    with pytest.raises(ScriptError, match=r"'half_smile' is not in the human library"):
        load_script(own / "half_smile.toml")  # without the head's library: the built-in one only
    with pytest.raises(ScriptError, match=rf"'glee' is not in the expression library {lib} \(or the human one\)"):
        load_script(own / "glee.toml", library=lib)


def test_play_plays_a_script_of_the_heads_own_expression(own: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = main(["play", str(own / "half_smile.toml"), "--head", str(own), "--emulate", "--duration", "0.6"])
    out, err = capsys.readouterr()
    assert status == 0, out + err
