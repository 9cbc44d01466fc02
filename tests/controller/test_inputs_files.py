"""Recorded tracker files -> Recordings: OpenFace 2.x, py-feat, JSON lines, blendshape CSV, MPEG-4 FAP.
Parsing on the generated samples and on small files written here; errors name file, line and column."""

from __future__ import annotations

from pathlib import Path

import pytest
from servoface.controller.inputs import (
    InputError,
    ReadOptions,
    load_recording,
    read_blendshape_csv,
    read_jsonl,
    read_openface_csv,
    read_pyfeat_csv,
)
from servoface.controller.inputs.fap import fap_to_aus, read_fap

SAMPLES = Path(__file__).resolve().parents[2] / "controller" / "inputs" / "samples"
OF_HEAD = " frame, face_id, timestamp, confidence, success, pose_Rx, AU01_r, AU12_r, AU45_r, AU12_c"


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_openface_sample_scales_and_holds_lost_rows() -> None:
    rec = read_openface_csv(SAMPLES / "openface_smile.csv", gaze=False, head_pose=False)
    assert len(rec) == 60 and rec.report.held == 5 and rec.duration_s == pytest.approx(59 / 30, abs=1e-3)
    peak = max(f.get("AU12") for f in rec.frames)
    assert peak == pytest.approx(0.7, abs=0.03)  # 3.5 on OpenFace's 0..5 scale
    lost = rec.frames[28:33]
    assert all(f.aus == rec.frames[27].aus for f in lost)  # "hold": the last good row
    assert set(rec.frames[10].aus) <= {f"AU{n}" for n in (1, 2, 4, 5, 6, 7, 9, 10, 12, 14, 15, 17, 20, 23, 25, 26, 45)}


def test_openface_neutral_policy_decays(tmp_path: Path) -> None:
    rows = [f"{i + 1}, 0, {i * 0.1:.1f}, 0.95, {0 if i >= 2 else 1}, 0.1, 0.0, 5.0, 0.0, 1" for i in range(6)]
    path = _write(tmp_path, "of.csv", OF_HEAD + "\n" + "\n".join(rows) + "\n")
    rec = read_openface_csv(path, lost="neutral", decay_s=0.3)
    values = [f.get("AU12") for f in rec.frames]
    assert values[:2] == [1.0, 1.0]
    assert values[2] == pytest.approx(2 / 3) and values[3] == pytest.approx(1 / 3) and values[4] == 0.0
    assert read_openface_csv(path, lost="hold").frames[5].get("AU12") == 1.0
    low = read_openface_csv(path, min_confidence=0.99)  # every row below the gate: neutral throughout
    assert all(f.get("AU12") == 0.0 for f in low.frames)


def test_openface_multi_face_and_mirror(tmp_path: Path) -> None:
    head = "frame,face_id,timestamp,confidence,success,AU12_r"
    body = "1,0,0.0,0.9,1,2.5\n1,1,0.0,0.9,1,5.0\n2,0,0.1,0.9,1,2.5\n2,1,0.1,0.9,1,5.0\n"
    path = _write(tmp_path, "multi.csv", head + "\n" + body)
    assert [f.get("AU12") for f in read_openface_csv(path).frames] == [0.5, 0.5]
    assert [f.get("AU12") for f in read_openface_csv(path, face_id=1).frames] == [1.0, 1.0]


OF_ERRORS = [
    ("no AU columns", "timestamp, confidence, success\n0.0, 0.9, 1\n", "no AU intensity columns"),
    ("text", OF_HEAD + "\n1, 0, 0.0, 0.9, 1, 0.1, 0.0, high, 0.0, 1\n", "line 2, column 'AU12_r'"),
    ("inf", OF_HEAD + "\n1, 0, 0.0, 0.9, 1, 0.1, 0.0, inf, 0.0, 1\n", "not finite"),
    ("range", OF_HEAD + "\n1, 0, 0.0, 0.9, 1, 0.1, 0.0, 9.0, 0.0, 1\n", "0..5"),
    ("short row", OF_HEAD + "\n1, 0, 0.0, 0.9, 1\n2, 0, 0.1, 0.9, 1, 0.1, 0.0, 1.0, 0.0, 1\n", "line 2: 5 cells"),
    ("success", OF_HEAD + "\n1, 0, 0.0, 0.9, 2, 0.1, 0.0, 1.0, 0.0, 1\n", "column 'success'"),
    (
        "time back",
        OF_HEAD + "\n1, 0, 0.5, 0.9, 1, 0.1, 0.0, 1.0, 0.0, 1\n2, 0, 0.4, 0.9, 1, 0.1, 0.0, 1.0, 0.0, 1\n",
        "line 3, column 'timestamp'",
    ),
    ("empty", "", "empty file"),
    ("header only", OF_HEAD + "\n", "no usable data rows"),
]


@pytest.mark.parametrize("what,text,named", OF_ERRORS, ids=[e[0] for e in OF_ERRORS])
def test_openface_errors_name_file_line_column(tmp_path: Path, what: str, text: str, named: str) -> None:
    path = _write(tmp_path, "bad.csv", text)
    with pytest.raises(InputError) as info:
        read_openface_csv(path, bad_rows="error")
    assert named in str(info.value) and "bad.csv" in str(info.value)


def test_pyfeat_sample_time_from_frame_and_no_face_row() -> None:
    rec = read_pyfeat_csv(SAMPLES / "pyfeat_surprise.csv", fps=30.0)
    assert len(rec) == 30 and rec.report.held == 1
    assert rec.frames[15].aus == rec.frames[14].aus
    mid = rec.sample(0.5)
    assert mid.get("AU1") > 0.9 and mid.get("AU26") > 0.7 and "AU43" in mid.aus


def test_pyfeat_partial_row_fills_the_empty_cell(tmp_path: Path) -> None:
    path = _write(tmp_path, "pf.csv", "frame,AU01,AU12\n0,0.1,0.2\n1,,0.3\n")
    rec = read_pyfeat_csv(path)
    assert rec.frames[1].get("AU1") == pytest.approx(0.1) and rec.report.cells_filled == 1


def test_jsonl_sample_and_errors(tmp_path: Path) -> None:
    rec = read_jsonl(SAMPLES / "arkit_smile.jsonl")
    mid = rec.sample(1.0)
    assert mid.get("AU12L") > 0.8 and mid.get("AU51") > 0.3 and mid.get("AU62") > 0.3
    assert read_jsonl(SAMPLES / "arkit_smile.jsonl", mirror=True).sample(1.0).get("AU12R") == mid.get("AU12L")
    bad = _write(tmp_path, "bad.jsonl", '{"t": 0, "aus": {"AU12": 0.2}}\n\n{"t": 0.1, "aus": {"AU12": 7}}\n')
    with pytest.raises(InputError, match=r"bad\.jsonl: line 3\.aus\.AU12"):
        read_jsonl(bad, bad_rows="error")
    no_t = _write(tmp_path, "no_t.jsonl", '{"t": 0, "aus": {"AU12": 0.2}}\n{"aus": {"AU12": 0.2}}\n')
    with pytest.raises(InputError, match="line 2.t"):
        read_jsonl(no_t)
    dog = _write(tmp_path, "dog.jsonl", '{"t": 0, "aus": {"AU7": -0.5}}\n{"t": 0.2, "aus": {"AU7": 0.5}}\n')
    assert read_jsonl(dog, "dog").sample(0.1).get("AU7") == pytest.approx(0.0)


def test_blendshape_csv_sample_and_live_link_face_layout(tmp_path: Path) -> None:
    rec = read_blendshape_csv(SAMPLES / "mediapipe_blink.csv")
    assert max(f.get("AU43L") for f in rec.frames) > 0.9 and rec.frames[-1].get("AU52") > 0.2
    llf = _write(
        tmp_path,
        "llf.csv",
        "Timecode,BlendShapeCount,EyeBlinkLeft,MouthSmileLeft,HeadYaw\n"
        "00:00:01:00.000,52,0.0,0.5,0.1\n00:00:01:30.000,52,1.0,0.5,0.1\n",
    )
    got = read_blendshape_csv(llf, fps=60.0)
    assert got.duration_s == pytest.approx(0.5) and got.frames[1].get("AU43L") == 1.0
    assert any("HeadYaw" in n for n in got.report.notes)
    extra = _write(tmp_path, "extra.csv", "t,mouthSmileLeft,grin\n0,0.1,0.2\n")
    assert read_blendshape_csv(extra).report.columns_ignored == ["grin"]
    out = _write(tmp_path, "out.csv", "t,mouthSmileLeft\n0,0.1\n0.1,1.4\n")
    with pytest.raises(InputError, match="line 3, column 'mouthSmileLeft'"):
        read_blendshape_csv(out, bad_rows="error")


def test_fap_sample_and_mapping(tmp_path: Path) -> None:
    rec = read_fap(SAMPLES / "greeting.fap")
    mid = rec.sample(0.5)
    assert mid.get("AU12L") > 0.5 and mid.get("AU1R") > 0.4 and mid.get("AU26") > 0.4
    aus = fap_to_aus({12: -128.0, 19: 1024.0, 49: 0.5 / 180 * 3.14159265 * 45 * 1e5})
    assert aus["AU15L"] == pytest.approx(0.5) and aus["AU43L"] == 1.0 and aus["AU51"] == pytest.approx(0.5, 1e-3)
    bad = _write(tmp_path, "bad.fap", "2.1 x 25 1\n" + " ".join(["1"] + ["0"] * 67) + "\n0 abc\n")
    with pytest.raises(InputError, match="line 3, column 2"):
        read_fap(bad, options=ReadOptions(bad_rows="error"))
    short = _write(tmp_path, "short.fap", "2.1 x 25 1\n1 0 1\n0 1\n")
    with pytest.raises(InputError, match="line 2: expected a mask of 68"):
        read_fap(short, options=ReadOptions(bad_rows="error"))


@pytest.mark.parametrize(
    "name,au",
    [("openface_smile.csv", "AU12"), ("pyfeat_surprise.csv", "AU1"), ("arkit_smile.jsonl", "AU12L"),
     ("mediapipe_blink.csv", "AU12L"), ("greeting.fap", "AU12L")],
)  # fmt: skip
def test_load_recording_picks_the_reader(name: str, au: str) -> None:
    rec = load_recording(SAMPLES / name)
    assert rec.face_type == "human" and max(f.get(au) for f in rec.frames) > 0.2
    assert rec.sample(-1.0).t_s == -1.0 and rec.sample(99.0).aus == rec.frames[-1].aus


def test_load_recording_refuses_unknown_and_dog_csv(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="cannot tell which tracker"):
        load_recording(_write(tmp_path, "x.txt", "hello"))
    with pytest.raises(InputError, match="dog"):
        load_recording(SAMPLES / "openface_smile.csv", "dog")


def test_openface_gaze_on_by_default(tmp_path: Path) -> None:
    rec = read_openface_csv(SAMPLES / "openface_smile.csv", gaze=True)
    first = rec.frames[0]  # gaze_angle_x = 0.05 rad (2.9 deg to the subject's left), y = 0.10 rad (down)
    assert first.get("AU61") == pytest.approx(2.8648 / 30, abs=1e-3) and first.get("AU62") == 0.0
    assert first.get("AU64") == pytest.approx(5.7296 / 20, abs=1e-3) and first.get("AU63") == 0.0
    assert "AU61" not in read_openface_csv(SAMPLES / "openface_smile.csv", gaze=False).frames[0].aus
