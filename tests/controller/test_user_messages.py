"""What a user meets at the Python prompt and in the files servoface writes: a misspelt name gets the
nearest one and the list, a bad argument is named as the caller wrote it, a result prints on one line,
and written files are readable by the rest of a team (not 0600)."""

from __future__ import annotations

import stat
from pathlib import Path

import numpy as np
import pytest
from servoface.controller.errors import ControllerError, ScriptError
from servoface.controller.face import Face
from servoface.controller.loop import LoopStats
from servoface.controller.performance import Performance
from servoface.controller.script import load_script


@pytest.fixture(scope="module")
def face() -> Face:  # type: ignore[misc]
    with Face.open("human", emulate=True) as opened:
        yield opened


def test_a_misspelt_expression_gets_the_nearest_name_and_the_list(face: Face) -> None:
    with pytest.raises(
        ControllerError, match=r"unknown expression 'hapiness' \(did you mean 'happiness'\?\); known: \["
    ):
        face.express("hapiness")
    with pytest.raises(ControllerError) as err:
        face.express("zzzz")
    assert "did you mean" not in str(err.value) and "known: [" in str(err.value)


def test_expresss_own_arguments_are_named_as_the_caller_wrote_them(face: Face) -> None:
    for kwargs, field in (
        ({"hold_s": -2}, "express: hold_s"),
        ({"transition_s": float("nan")}, "express: transition_s"),
    ):
        with pytest.raises(ControllerError, match=field):
            face.express("happiness", **kwargs)  # type: ignore[arg-type]


def test_a_misspelt_shipped_script_gets_the_nearest_name_and_the_list() -> None:
    with pytest.raises(
        ScriptError, match=r"did you mean 'human_performance'\?\); shipped scripts: \[.*'dog_performance'"
    ):
        load_script("human_performnce")
    with pytest.raises(ScriptError) as err:  # a path is a path: no list of names
        load_script("nosuch/folder/x.toml")
    assert "shipped scripts" not in str(err.value) and "cannot read script" in str(err.value)


def test_a_performance_prints_on_one_line() -> None:
    stats = LoopStats(rate_hz=50.0)
    stats.recent_lateness_s.extend([0.001] * 1000)
    text = repr(Performance(stats=stats, interrupted=True, bus_failure="servo 3 gone"))
    assert "\n" not in text and len(text) < 200, text
    assert text.startswith("Performance(frames=0, verdicts={'accept': 0") and "bus_failure='servo 3 gone'" in text


def test_files_written_atomically_are_not_private(tmp_path: Path) -> None:
    from servoface.controller.speech.audio import write_wav
    from servoface.controller.speech.script_out import write_script
    from servoface.controller.studio.scripts import ScriptFolder

    written = [
        write_wav(tmp_path / "speech.wav", np.zeros(160, dtype=np.int16), 16000),
        write_script(tmp_path / "speech.toml", "[script]\nface = 'human'\n"),
    ]
    folder = ScriptFolder(tmp_path / "studio", None)
    text = "[script]\nface = 'human'\n\n[[play]]\nat_s = 0.0\nlibrary = 'happiness'\n"
    saved = folder.save("greeting.toml", text, "text")
    written.append(Path(saved["path"]))
    for path in written:
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path
