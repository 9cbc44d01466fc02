"""AUFrame validation: every kind of bad input is a FrameError that names the AU and what was expected."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from servoface.controller.au_names import builtin_au_names, canonical_au, default_au_names
from servoface.controller.errors import FrameError
from servoface.controller.frame import AUFrame, FrameValidator, validate_aus


def test_valid_human_frame_is_canonical_and_read_only() -> None:
    frame = AUFrame(0.5, {"au12l": 0.8, "AU01": 0.2, "AU45": 1}, "human")
    assert dict(frame.aus) == {"AU12L": 0.8, "AU1": 0.2, "AU45": 1.0}
    assert frame.get("AU12L") == 0.8 and frame.get("AU4") == 0.0 and frame["au1"] == 0.2
    with pytest.raises(TypeError):
        frame.aus["AU12L"] = 0.1  # type: ignore[index]


def test_dfacs_is_signed_and_human_is_not() -> None:
    assert AUFrame(0.0, {"AU7": -0.5}, "dog").get("AU7") == -0.5
    with pytest.raises(FrameError, match=r"AU7.*out of range.*expected 0..1"):
        AUFrame(0.0, {"AU7": -0.5}, "human")


@pytest.mark.parametrize(
    ("aus", "face", "needle"),
    [
        ({"AU12": math.nan}, "human", r"AU12: expected a finite"),
        ({"AU12": math.inf}, "human", r"AU12: expected a finite"),
        ({"AU12": 1.5}, "human", r"AU12: FACS intensity 1.5 is out of range, expected 0..1"),
        ({"AU7": -1.2}, "dog", r"AU7: DFACS intensity -1.2 is out of range, expected -1..1"),
        ({"AU12": "high"}, "human", r"AU12: expected a number"),
        ({"AU12": True}, "human", r"AU12: expected a number"),
        ({"AU99": 0.1}, "human", r"AU99: AU99 is not an AU of the human face; expected one of"),
        ({"AU3": 0.1}, "human", r"AU3: AU3 is not an AU of the human face"),
        ({"AU25": 0.1}, "dog", r"AU25: AU25 is not an AU of the dog face"),
        ({"AU17L": 0.1}, "human", r"AU17L: AU17L is not an AU of the human face"),
        ({"smile": 0.1}, "human", r"'smile' is not an AU name; expected 'AU<number>'"),
        ({"-AU7": 0.5}, "dog", r"counter AU is a negative value on the plain name"),
        ({"AU7c": 0.5}, "dog", r"counter AU is a negative value on the plain name"),
        ({"AU12": 0.1, "au12": 0.2}, "human", r"au12: AU12 is given twice"),
        ({"AU15": -0.5}, "dog", r"AU15: DFACS intensity -0.5 is out of range, expected 0..1"),
    ],
)
def test_each_kind_of_bad_frame_names_the_field(aus: dict[str, object], face: str, needle: str) -> None:
    with pytest.raises(FrameError, match=needle):
        AUFrame(1.0, aus, face)  # type: ignore[arg-type]


@pytest.mark.parametrize("t_s", [math.nan, math.inf, "0", None, True])
def test_bad_time_is_rejected(t_s: object) -> None:
    with pytest.raises(FrameError, match=r"t_s: expected a finite time"):
        AUFrame(t_s, {"AU12": 0.1})  # type: ignore[arg-type]


def test_without_a_face_only_the_universal_rules_apply() -> None:
    assert AUFrame(0.0, {"AU99": -1.0}).get("AU99") == -1.0
    with pytest.raises(FrameError, match="AU99"):
        AUFrame(0.0, {"AU99": -1.01})


def test_bad_face_type_and_non_mapping() -> None:
    with pytest.raises(FrameError, match="face type: expected 'human' or 'dog', got 'cat'"):
        AUFrame(0.0, {}, "cat")  # type: ignore[arg-type]
    with pytest.raises(FrameError, match="expected a mapping"):
        validate_aus([("AU12", 0.1)], "human")  # type: ignore[arg-type]


def test_validator_takes_the_allowed_set_as_a_parameter() -> None:
    only = FrameValidator("human", frozenset({"AU12", "AU6"}))
    assert only(0.1, {"AU12": 0.5}).get("AU12") == 0.5
    with pytest.raises(FrameError, match="AU1: AU1 is not an AU of the human face; expected one of AU6, AU12"):
        only(0.1, {"AU1": 0.5})
    with pytest.raises(FrameError, match=r"poses\.smile\.AU1:"):
        only.pose({"AU1": 0.5}, where="poses.smile")


def test_default_names_match_the_builtin_sets() -> None:
    for face in ("human", "dog"):
        assert default_au_names(face) >= builtin_au_names(face) - {"AU3"}  # type: ignore[arg-type]
        assert "AU12L" in default_au_names("human") and "AU61" in default_au_names("human")
        assert "AU19" in default_au_names("dog") and "AU51" not in default_au_names("dog")


def test_canonical_names() -> None:
    assert canonical_au("au4l") == "AU4L"
    assert canonical_au("AU045") == "AU45"
    for stray in (" AU045 ", "AU12\n", "AU１２", "AU\u200b12"):  # matched exactly: ASCII digits, no whitespace
        with pytest.raises(FrameError):
            canonical_au(stray)
    with pytest.raises(FrameError):
        canonical_au(12)  # type: ignore[arg-type]


@given(st.dictionaries(st.sampled_from(sorted(default_au_names("dog"))), st.floats(allow_nan=True)))
def test_property_a_dog_frame_is_either_valid_or_rejected(aus: dict[str, float]) -> None:
    ok = all(math.isfinite(v) and -1 <= v <= 1 for v in aus.values()) and not any(
        v < 0 and k.rstrip("LR") in ("AU15", "AU16") for k, v in aus.items()
    )
    try:
        frame = AUFrame(0.0, aus, "dog")
    except FrameError:
        assert not ok
    else:
        assert ok and dict(frame.aus) == {k: float(v) for k, v in aus.items()}


def test_allowed_set_without_a_face_is_an_error() -> None:
    with pytest.raises(FrameError, match="allowed: an allowed AU-name set needs face_type"):
        AUFrame(0.0, {"AU12": 0.1}, allowed=frozenset({"AU12"}))


def test_validator_for_a_head_uses_its_au_table(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from servoface.sim.au import au_table_path as table_path

    class BuiltinHead:
        name, face_type, au_table_path = "human", "human", table_path("human")

    validator = FrameValidator.for_head(BuiltinHead())
    assert validator.face_type == "human" and "AU12L" in validator.names
    bad = tmp_path / "au.toml"
    bad.write_text("not toml [", encoding="utf-8")

    class BrokenHead:
        name, face_type, au_table_path = "mine", "human", bad

    with pytest.raises(FrameError, match="head mine: cannot read its AU table"):
        FrameValidator.for_head(BrokenHead())
