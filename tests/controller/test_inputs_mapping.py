"""Blendshape -> AU prior (facs-human.md §3), mirror mode, head pose and eye look, message validation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from servoface.controller.inputs import InputError, MessageDecoder, load_blendshape_map, mirror_aus
from servoface.controller.inputs.head_pose import head_pose_aus, matrix_to_ypr_deg, ypr_matrix

# Transcribed independently from facs-human.md §3 (sided AUs on the subject's own side; AU24 is a midline
# AU in servoface's set, so both press shapes give AU24; AU29/AU30 are not in servoface's human set).
SHEET: dict[str, set[str]] = {
    "browInnerUp": {"AU1"},
    "browOuterUpLeft": {"AU2L"}, "browOuterUpRight": {"AU2R"},
    "browDownLeft": {"AU4L"}, "browDownRight": {"AU4R"},
    "eyeWideLeft": {"AU5L"}, "eyeWideRight": {"AU5R"},
    "cheekSquintLeft": {"AU6L"}, "cheekSquintRight": {"AU6R"},
    "eyeSquintLeft": {"AU7L"}, "eyeSquintRight": {"AU7R"},
    "eyeBlinkLeft": {"AU43L"}, "eyeBlinkRight": {"AU43R"},
    "noseSneerLeft": {"AU9L"}, "noseSneerRight": {"AU9R"},
    "mouthUpperUpLeft": {"AU10L"}, "mouthUpperUpRight": {"AU10R"},
    "mouthSmileLeft": {"AU12L"}, "mouthSmileRight": {"AU12R"},
    "mouthDimpleLeft": {"AU14L"}, "mouthDimpleRight": {"AU14R"},
    "mouthFrownLeft": {"AU15L"}, "mouthFrownRight": {"AU15R"},
    "mouthLowerDownLeft": {"AU16L"}, "mouthLowerDownRight": {"AU16R"},
    "mouthShrugLower": {"AU17"}, "mouthShrugUpper": set(),
    "mouthPucker": {"AU18"},
    "mouthStretchLeft": {"AU20L"}, "mouthStretchRight": {"AU20R"},
    "mouthFunnel": {"AU22"},
    "mouthPressLeft": {"AU24"}, "mouthPressRight": {"AU24"},
    "mouthRollUpper": {"AU28"}, "mouthRollLower": {"AU28"},
    "jawOpen": {"AU25", "AU26", "AU27"},
    "jawForward": set(), "jawLeft": set(), "jawRight": set(),
    "cheekPuff": {"AU34"}, "tongueOut": {"AU19"},
    "mouthClose": set(), "mouthLeft": set(), "mouthRight": set(), "_neutral": set(),
    "eyeLookOutLeft": {"AU61"}, "eyeLookInLeft": {"AU62"}, "eyeLookInRight": {"AU61"},
    "eyeLookOutRight": {"AU62"}, "eyeLookUpLeft": {"AU63"}, "eyeLookUpRight": {"AU63"},
    "eyeLookDownLeft": {"AU64"}, "eyeLookDownRight": {"AU64"},
}  # fmt: skip


def test_table_covers_arkit_and_mediapipe_names() -> None:
    bmap = load_blendshape_map()
    assert bmap.names == frozenset(SHEET)
    assert len(bmap.names - {"_neutral"}) == 52 and len(bmap.names - {"tongueOut"}) == 52


@pytest.mark.parametrize("shape", sorted(SHEET))
def test_each_blendshape_maps_to_the_sheets_aus(shape: str) -> None:
    aus = load_blendshape_map().to_aus({shape: 1.0})
    assert {k for k, v in aus.items() if v > 1e-9} == SHEET[shape]
    assert all(0.0 <= v <= 1.0 for v in aus.values())
    assert load_blendshape_map().to_aus({shape: 0.0}) == {k: 0.0 for k in aus}


def test_jaw_open_ramps_are_monotone_and_reach_full_open() -> None:
    bmap = load_blendshape_map()
    jaw = [
        4 * a.get("AU25", 0) + 15 * a.get("AU26", 0) + 25 * a.get("AU27", 0)
        for a in (bmap.to_aus({"jawOpen": x}) for x in np.linspace(0, 1, 21))
    ]
    assert all(b >= a for a, b in zip(jaw, jaw[1:], strict=False))
    assert jaw[0] == 0.0 and jaw[-1] == pytest.approx(25.0, abs=0.01)


def test_eye_look_subject_right_is_out_right_plus_in_left() -> None:
    aus = load_blendshape_map().to_aus({"eyeLookOutRight": 0.6, "eyeLookInLeft": 0.6})
    assert aus["AU62"] == pytest.approx(0.6) and aus["AU61"] == 0.0
    both_up = load_blendshape_map().to_aus({"eyeLookUpLeft": 0.4, "eyeLookUpRight": 0.4})
    assert both_up["AU63"] == pytest.approx(0.4) and both_up["AU64"] == 0.0
    crossed = load_blendshape_map().to_aus({"eyeLookInLeft": 0.5, "eyeLookInRight": 0.5}, vergence=True)
    assert crossed["AU66"] == pytest.approx(0.5) and crossed["AU61"] == crossed["AU62"] == 0.0


def test_mirror_swaps_sides_and_lateral_head_eye_actions() -> None:
    bmap = load_blendshape_map()
    plain = bmap.to_aus({"mouthSmileLeft": 0.7, "browDownRight": 0.3, "eyeLookOutLeft": 0.8, "browInnerUp": 0.2})
    mirrored = bmap.to_aus(
        {"mouthSmileLeft": 0.7, "browDownRight": 0.3, "eyeLookOutLeft": 0.8, "browInnerUp": 0.2}, mirror=True
    )
    assert plain["AU12L"] == 0.7 and "AU12R" not in plain
    assert mirrored["AU12R"] == 0.7 and "AU12L" not in mirrored
    assert mirrored["AU4L"] == 0.3 and mirrored["AU1"] == 0.2
    assert plain["AU61"] == pytest.approx(0.4) and mirrored["AU62"] == pytest.approx(0.4)
    head = mirror_aus(head_pose_aus(20.0, 10.0, 8.0), "human")
    assert head["AU52"] > 0 and head["AU51"] == 0 and head["AU53"] > 0 and head["AU56"] > 0
    dog = mirror_aus({"AU10": 0.5, "AU1L": 0.3, "AU9": -0.2}, "dog")
    assert dog == {"AU10": -0.5, "AU1R": 0.3, "AU9": -0.2}


@pytest.mark.parametrize("ypr", [(20.0, 0.0, 0.0), (-30.0, 10.0, 0.0), (5.0, -15.0, 12.0), (0.0, 0.0, -10.0)])
def test_head_matrix_round_trip_and_aus(ypr: tuple[float, float, float]) -> None:
    got = matrix_to_ypr_deg(ypr_matrix(*ypr).tolist())
    assert got == pytest.approx(ypr, abs=1e-9)
    m4 = np.eye(4)
    m4[:3, :3] = ypr_matrix(*ypr)
    m4[:3, 3] = (10.0, -5.0, -400.0)
    assert matrix_to_ypr_deg(m4.ravel().tolist()) == pytest.approx(ypr, abs=1e-9)


def test_head_pose_aus_scales_and_signs() -> None:
    aus = head_pose_aus(22.5, -12.5, 10.0)  # AU51 full = 45 deg, AU54 full = 25, AU55 full = 20
    assert aus["AU51"] == pytest.approx(0.5) and aus["AU52"] == 0.0
    assert aus["AU54"] == pytest.approx(0.5) and aus["AU53"] == 0.0
    assert aus["AU55"] == pytest.approx(0.5) and aus["AU56"] == 0.0
    assert head_pose_aus(-90.0, 0.0, 0.0)["AU52"] == 1.0  # saturates


def test_frontal_face_matrix_is_neutral() -> None:
    aus = MessageDecoder().decode({"head": {"matrix": np.eye(4).tolist()}}).aus
    assert all(v == 0.0 for v in aus.values()) and "AU51" in aus


BAD: list[tuple[object, str]] = [
    ({"aus": {"AU12": 1.5}}, "aus.AU12"),
    ({"aus": {"AU12": "big"}}, "aus.AU12"),
    ({"aus": {"AU99": 0.1}}, "AU99"),
    ({"aus": {"AU12": 0.2}, "extra": 1}, "extra"),
    ({"blendshapes": {"mouthSmileLeft": 1.2}}, "blendshapes.mouthSmileLeft"),
    ({"blendshapes": {"mouthSmileLeft": -0.15}}, "blendshapes.mouthSmileLeft"),
    ({"blendshapes": {"smile": 0.5}}, "blendshapes.smile"),
    ({"blendshapes": {"jawOpen": True}}, "blendshapes.jawOpen"),
    ({"blendshapes": [0.1, 0.2]}, "blendshapes"),
    ({"head": {"yaw_deg": 400}}, "head.yaw_deg"),
    ({"head": {"yaw": 10}}, "head"),
    ({"head": {"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}}, "head.matrix"),
    ({"head": {"matrix": [1, 2, 3]}}, "head.matrix"),
    ({"t": "now", "aus": {}}, "message.t"),
    ({"confidence": 2.0, "aus": {}}, "confidence"),
    ({"t": 1.0}, "no face data"),
    ([1, 2], "JSON object"),
]


@pytest.mark.parametrize("msg,named", BAD, ids=[b[1] for b in BAD])
def test_bad_message_field_is_named(msg: object, named: str) -> None:
    with pytest.raises(InputError, match=named.replace(".", r"\.")):
        MessageDecoder().decode(msg)


def test_json_text_nan_and_garbage_rejected() -> None:
    dec = MessageDecoder()
    for text in ('{"aus": {"AU12": NaN}}', '{"aus": {"AU12": Infinity}}', "{not json", b"\xff\xfe"):
        with pytest.raises(InputError, match="JSON"):
            dec.decode_line(text)
    with pytest.raises(InputError, match="bytes"):
        dec.decode_line("x" * 70_000)


def test_dog_takes_dfacs_aus_but_not_blendshapes() -> None:
    dec = MessageDecoder("dog", mirror=True)
    msg = dec.decode({"t": 0.5, "aus": {"AU7": -0.4, "AU5L": 0.6, "AU10": 0.3}})
    assert msg.aus == {"AU7": -0.4, "AU5R": 0.6, "AU10": -0.3}
    with pytest.raises(InputError, match="human AUs only"):
        dec.decode({"blendshapes": {"jawOpen": 0.2}})
    with pytest.raises(InputError, match="aus.AU7"):
        dec.decode({"aus": {"AU7": -1.5}})


def test_explicit_aus_override_mapped_ones() -> None:
    msg = MessageDecoder().decode({"blendshapes": {"mouthSmileLeft": 0.9}, "aus": {"AU12L": 0.1}})
    assert msg.aus["AU12L"] == 0.1 and not math.isnan(msg.confidence)


def test_shape_ranges_rescale_per_user_and_round_trip(tmp_path: Path) -> None:
    from servoface.controller.inputs import ShapeRanges

    # a user whose eyeWide never exceeds 0.06 and whose smile rests at 0.1 (mediapipe #4450)
    samples = [{"eyeWideLeft": 0.06 * k / 20, "mouthSmileLeft": 0.1 + 0.7 * k / 20, "jawOpen": 0.3} for k in range(21)]
    ranges = ShapeRanges.from_samples(samples)
    assert "jawOpen" not in ranges.ranges  # it never moved
    bmap = load_blendshape_map()
    aus = bmap.to_aus({"eyeWideLeft": 0.06, "mouthSmileLeft": 0.1, "jawOpen": 0.3}, ranges=ranges)
    assert aus["AU5L"] == pytest.approx(1.0) and aus["AU12L"] == 0.0 and aus["AU26"] > 0.3
    path = tmp_path / "ranges.json"
    ranges.save(path)
    loaded = ShapeRanges.load(path, bmap.names)
    assert loaded.ranges.keys() == ranges.ranges.keys()
    dec = MessageDecoder(shape_ranges=loaded)
    rest, full = loaded.ranges["eyeWideLeft"]
    assert rest == pytest.approx(0.003) and full == pytest.approx(0.06)  # 5th / 99th percentiles
    assert dec.decode({"blendshapes": {"eyeWideLeft": 0.03}}).aus["AU5L"] == pytest.approx(0.027 / 0.057)
    path.write_text('{"schema_version": 1, "ranges": {"eyeWideLeft": [0.2, 0.1]}}')
    with pytest.raises(InputError, match="ranges.eyeWideLeft"):
        ShapeRanges.load(path)
    path.write_text('{"schema_version": 1, "ranges": {"eyeWider": [0.0, 0.1]}}')
    with pytest.raises(InputError, match="ranges.eyeWider"):
        ShapeRanges.load(path, bmap.names)


def test_other_spellings_of_shape_names_are_accepted() -> None:
    bmap = load_blendshape_map()
    for spelling in ("EyeBlinkLeft", "EYE_BLINK_LEFT", "eyeblinkleft"):
        assert bmap.to_aus({spelling: 1.0}) == {"AU43L": 1.0}
    assert bmap.to_aus({"NEUTRAL": 0.9}) == {}
    with pytest.raises(InputError, match="given twice"):
        bmap.to_aus({"eyeBlinkLeft": 0.1, "EYE_BLINK_LEFT": 0.2})


def test_shape_ranges_are_written_atomically(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A write that fails half way (disk full, the run killed before the rename) leaves the old file whole
    and no temp file behind; the error names the file."""
    import os

    from servoface.controller.inputs import ShapeRanges

    path = tmp_path / "ranges.json"
    old = ShapeRanges({"eyeWideLeft": (0.0, 0.06)})
    old.save(path)
    before = path.read_text()

    def full_disk(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full_disk)
    with pytest.raises(InputError, match="ranges.json"):
        ShapeRanges({"eyeWideLeft": (0.0, 0.5)}).save(path)
    monkeypatch.undo()
    assert path.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ranges.json"]
    assert ShapeRanges.load(path).ranges == {"eyeWideLeft": (0.0, 0.06)}


def test_an_own_blendshape_table_that_is_a_folder_or_too_large_is_refused(tmp_path: Path) -> None:
    """Before: ``load_blendshape_map(path)`` read any file whole, however large; a folder was an OSError."""
    big = tmp_path / "shapes.toml"
    with big.open("wb") as fh:
        fh.truncate(16 * 2**20 + 1)
    with pytest.raises(InputError, match=r"shapes\.toml: 16777217 bytes; a blendshape table is at most 16 MiB"):
        load_blendshape_map(big)
    with pytest.raises(InputError, match=r"a directory, not a regular file; expected a blendshape table"):
        load_blendshape_map(tmp_path)
