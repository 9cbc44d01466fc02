"""Measured input on a head whose own AU table narrows an AU (AU12 at most 0.5): tracker files and live streams
are held inside the head's ranges and counted, not refused, so a full smile plays as the widest smile the
head has. Before, `play --input` of a smiling OpenFace file stopped at the first frame above 0.5 with
"AU12: expected a finite intensity in [0.0, 0.5]", after the head had been opened; a stream skipped
every such frame, so the face froze for as long as the person smiled."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from servoface.controller.cli import main as cli_main
from servoface.controller.inputs import HeadRanges, InputError, MessageDecoder, fit_recording, load_recording
from servoface.sim.heads import load_head

from tests.controller.test_inputs_files import SAMPLES
from tests.human_copy import narrow_au_copy


@pytest.fixture(scope="module")
def narrow(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return narrow_au_copy(tmp_path_factory.mktemp("heads") / "narrow_au")


def test_head_ranges_are_the_heads_own_narrower_ones(narrow: Path) -> None:
    ranges = HeadRanges.of(load_head(str(narrow)))
    assert ranges.narrow == {"AU12": (0.0, 0.5), "AU12L": (0.0, 0.5), "AU12R": (0.0, 0.5)}
    assert HeadRanges.of(load_head("human")).narrow == {}  # the built-in human takes 0..1 everywhere
    dog = HeadRanges.of(load_head("dog")).narrow  # DFACS blink and lick have no counter AU: 0..1 of -1..1
    assert dog["AU15"] == (0.0, 1.0) and dog["AU16"] == (0.0, 1.0) and "AU1" not in dog


def test_saturate_holds_values_at_the_ends_and_names_them(narrow: Path) -> None:
    ranges = HeadRanges.of(load_head(str(narrow)))
    aus, moved = ranges.saturate({"AU12L": 0.9, "AU12R": 0.4, "AU6": 1.0})
    assert aus == {"AU12L": 0.5, "AU12R": 0.4, "AU6": 1.0} and moved == ["AU12L"]
    dog = HeadRanges.of(load_head("dog"))
    assert dog.saturate({"AU15": -0.3, "AU5": -0.3}) == ({"AU15": 0.0, "AU5": -0.3}, ["AU15"])


def test_decoder_saturates_to_the_head_and_still_refuses_what_no_face_takes(narrow: Path) -> None:
    decoder = MessageDecoder.for_head(load_head(str(narrow)))
    assert decoder.decode({"aus": {"AU12": 0.8, "AU6": 0.7}}).aus == {"AU12": 0.5, "AU6": 0.7}
    smile = decoder.decode({"blendshapes": {"mouthSmileLeft": 1.0, "mouthSmileRight": 1.0}}).aus
    assert smile["AU12L"] == 0.5 and smile["AU12R"] == 0.5
    assert decoder.saturated == {"AU12": 1, "AU12L": 1, "AU12R": 1}
    with pytest.raises(InputError, match=r"message\.aus\.AU12: FACS intensity 3 is out of range, expected 0\.\.1"):
        decoder.decode({"aus": {"AU12": 3}})  # outside every human face's range: the message is refused
    with pytest.raises(InputError, match="AU99"):
        decoder.decode({"aus": {"AU99": 0.5}})
    assert decoder.saturated == {"AU12": 1, "AU12L": 1, "AU12R": 1}  # nothing counted for refused messages


def test_a_recording_is_fitted_and_its_report_says_so(narrow: Path) -> None:
    head = load_head(str(narrow))
    raw = load_recording(SAMPLES / "openface_smile.csv", "human")
    above = sum(1 for f in raw.frames if f.aus.get("AU12", 0.0) > 0.5)
    assert above > 0  # the sample smiles beyond this head's range
    fitted = fit_recording(raw, HeadRanges.of(head))
    assert max(f.aus.get("AU12", 0.0) for f in fitted.frames) == 0.5
    assert max(fitted.sample(t / 50).aus.get("AU12", 0.0) for t in range(200)) <= 0.5  # interpolation too
    assert [f.t_s for f in fitted.frames] == [f.t_s for f in raw.frames]
    note = f"{above} values beyond the AU ranges of head 'narrow_au' held at their ends: AU12 {above} x (0..0.5)"
    assert note in fitted.report.notes
    assert note not in raw.report.notes and fit_recording(raw, HeadRanges.of(head)).report.notes.count(note) == 1
    unchanged = load_recording(SAMPLES / "openface_smile.csv", "human")
    assert fit_recording(unchanged, HeadRanges.of(load_head("human"))) is unchanged


def test_play_input_plays_a_full_smile_to_its_end_on_the_narrow_head(
    narrow: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    status = cli_main(["play", "--head", str(narrow), "--input", "sample:openface_smile", "--emulate"])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    assert "stop (end)" in out + err and "ActionUnitValueError" not in out + err
    assert "held at their ends: AU12" in out


def test_stream_follows_a_full_smile_on_the_narrow_head(
    narrow: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    lines = [json.dumps({"t": k / 30, "aus": {"AU12": min(1.0, 0.1 * k)}}) for k in range(12)]
    monkeypatch.setattr("sys.stdin", io.StringIO("\n".join(lines) + "\n"))
    argv = ["stream", "--emulate", "--stdin", "--arrival", "--duration", "0.4", "--head", str(narrow)]
    assert cli_main(argv) == 0
    out = capsys.readouterr().out
    assert "messages 12: good 12, bad 0" in out
    assert "values beyond the AU ranges of head 'narrow_au' held at their ends: AU12 6 x (0..0.5)" in out
