"""Issue #12: the file variations real trackers write (OpenFace 2.x, py-feat, Live Link Face, MediaPipe, Greta /
Xface FAP), each made here, read through the API and through `servoface play --input` (whose printed summary
is asserted); plus time units, faces, rest pose, head pose, FAP 61/62, --hold for a still and preview --input."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from servoface.controller.cli import main as cli_main
from servoface.controller.face import Face
from servoface.controller.inputs import InputError, ReadOptions, detect_format, load_recording
from servoface.controller.inputs.fap import fap_to_aus
from servoface.controller.inputs.head_pose import openface_pose_deg

OF = "frame, face_id, timestamp, confidence, success, AU01_r, AU12_r"


@pytest.fixture(scope="module", autouse=True)
def _warm_head() -> Iterator[None]:
    """Build the head's twin once before the CLI runs: the first build in a process is CPU-heavy, and on a
    loaded machine it can starve the emulated chain's replies while `play` opens the bus."""
    face = Face.open("human", emulate=True, wire_time=False)
    face.close(ease_s=0.0)
    yield


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _play(path: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> str:
    """`servoface play --input PATH` on the emulator for a few frames; the printed summary (stdout)."""
    rc = cli_main(["play", "--emulate", "--input", str(path), "--duration", "0.06", *extra])
    out, err = capsys.readouterr()
    assert rc == 0, out + err
    assert "frames; verdicts" in out
    return out


def _of_rows(n: int, step: float = 1 / 30, *, au12: float = 2.5) -> str:
    return "\n".join(f"{i + 1}, 0, {i * step:.6g}, 0.98, 1, 0.5, {au12}" for i in range(n)) + "\n"


# -- refused before -----------------------------------------------------------------------------------------
def test_openface_saved_as_dot_openface(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "take.openface", OF + "\n" + _of_rows(6))
    assert detect_format(path) == "openface"
    assert load_recording(path).frames[0].get("AU12") == pytest.approx(0.5)
    assert "take.openface: OpenFace CSV: 6 rows used" in _play(path, capsys)


def test_openface_without_success_and_confidence(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "au_only.csv", "timestamp,AU12_r\n0.0,5\n0.033,2.5\n")
    rec = load_recording(path)
    assert [f.get("AU12") for f in rec.frames] == [1.0, 0.5] and rec.report.held == 0
    assert "no confidence / success column: every row read as tracked" in _play(path, capsys)


def test_live_link_face_eye_look_slightly_above_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = [f"00:00:01:{k:02d}.000,52,{1.0033 + 0.073 * (k % 2):.4f},0.4" for k in range(10)]
    path = _write(tmp_path, "llf.csv", "Timecode,BlendShapeCount,EyeLookInRight,MouthSmileLeft\n" + "\n".join(rows))
    rec = load_recording(path)
    assert len(rec) == 10 and rec.report.cells_clamped == 10  # 1.0033 and 1.0763: within 10 % of the range
    assert rec.frames[0].get("AU12L") == pytest.approx(0.4)
    out = _play(path, capsys)
    assert "blendshape CSV: 10 rows used" in out and "10 values slightly outside their range clamped" in out
    beyond = _write(tmp_path, "beyond.csv", "t,eyeLookInRight\n0,0.2\n0.1,1.5\n0.2,0.3\n")
    got = load_recording(beyond)
    assert len(got) == 2 and got.report.skipped == {"a score outside 0..1": 1}
    with pytest.raises(InputError, match=r"line 3, column 'eyeLookInRight'.*1\.5 is outside"):
        load_recording(beyond, options=ReadOptions(bad_rows="error"))


def _mp_result(ts_ms: int, scores: dict[str, float], faces: int = 1) -> str:
    cats = [{"index": i, "score": v, "category_name": k, "display_name": ""} for i, (k, v) in enumerate(scores.items())]
    return json.dumps({"timestamp_ms": ts_ms, "face_blendshapes": [cats] * faces, "face_landmarks": [[]] * faces})


def test_mediapipe_python_result_shape_and_timestamp_ms(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = [_mp_result(33 * k, {"_neutral": 0.9, "mouthSmileLeft": 0.1 * k, "jawOpen": 0.0}) for k in range(8)]
    lines.insert(4, json.dumps({"timestamp_ms": 132, "face_blendshapes": [], "face_landmarks": []}))  # nobody seen
    path = _write(tmp_path, "mp.json", "\n".join(lines) + "\n")
    rec = load_recording(path)
    assert len(rec) == 9 and rec.report.held == 1 and rec.duration_s == pytest.approx(0.231)
    assert rec.frames[-1].get("AU12L") == pytest.approx(0.7)
    out = _play(path, capsys)
    assert "JSON lines: 8 rows used, 1 filled by the lost-tracking policy" in out
    csv = _write(tmp_path, "mp.csv", "timestamp_ms,mouthSmileLeft\n0,0.1\n33,0.2\n66,0.3\n")
    got = load_recording(csv)
    assert got.duration_s == pytest.approx(0.066)
    assert "timestamp_ms in ms (from the column name" in _play(csv, capsys)


def test_greta_fap_name_with_a_space_and_69_masks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mask = ["0"] * 69
    mask[12] = mask[13] = "1"  # FAP 12 and 13 (index = FAP number in a 69-value mask): corner lips up
    body = "".join(f"{' '.join(mask)}\n{k} {64 * k} {64 * k}\n" for k in range(4))
    path = _write(tmp_path, "greta smile.fap", f"2.1 greta smile take 25 4\n{body}")
    rec = load_recording(path)
    assert len(rec) == 4 and rec.duration_s == pytest.approx(3 / 25)
    assert rec.frames[-1].get("AU12L") == pytest.approx(0.75) and rec.frames[-1].get("AU12R") == pytest.approx(0.75)
    out = _play(path, capsys)
    assert "MPEG-4 FAP: 4 rows used" in out and "69-value masks (FAPs 0..68, Greta)" in out
    assert "animation 'greta smile take'" in out


def test_live_link_face_camel_and_snake_case_headers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    camel = _write(tmp_path, "camel.csv", "timecode,blendShapeCount,eyeBlinkLeft,headYaw\n00:00:00:00,52,0.5,0.1\n")
    snake = _write(
        tmp_path, "snake.csv", "TIMECODE,BLEND_SHAPE_COUNT,EYE_BLINK_LEFT,HEAD_YAW\n00:00:00:00,52,0.5,0.1\n"
    )
    for path in (camel, snake):
        rec = load_recording(path)
        assert rec.frames[0].get("AU43L") == pytest.approx(0.5) and "AU51" not in rec.frames[0].aus
        out = _play(path, capsys)
        assert "Live Link Face head/eye rotation columns ignored" in out and "columns ignored (2)" in out


def test_pandas_index_column_and_trailing_comma(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pandas = _write(tmp_path, "fex.csv", ",frame,AU01,AU12\n0,0,0.1,0.2\n1,1,0.1,0.4\n")
    trailing = _write(tmp_path, "trail.csv", "frame,AU01,AU12,\n0,0.1,0.2,\n1,0.1,0.4,\n")
    for path in (pandas, trailing):
        rec = load_recording(path)
        assert [f.get("AU12") for f in rec.frames] == [0.2, 0.4]
        assert "unnamed columns ignored (pandas index / trailing separator)" in _play(path, capsys)


def test_truncated_last_row_is_skipped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "cut.csv", OF + "\n" + _of_rows(5) + "6, 0, 0.16")
    rec = load_recording(path)
    assert len(rec) == 5 and rec.report.skipped == {"truncated last row": 1}
    out = _play(path, capsys)
    assert "5 rows used, 1 skipped" in out and "skipped 1 x truncated last row" in out


def test_single_nan_or_empty_au_cell_is_filled(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = OF + "\n1, 0, 0.0, 0.98, 1, 0.5, 2.5\n2, 0, 0.033, 0.98, 1, nan, 3.0\n3, 0, 0.066, 0.98, 1, 0.5, \n"
    path = _write(tmp_path, "holes.csv", text)
    rec = load_recording(path)
    assert [f.get("AU1") for f in rec.frames] == [0.1, 0.1, 0.1]  # NaN -> the previous row's value
    assert [f.get("AU12") for f in rec.frames] == [0.5, 0.6, 0.6]
    assert "2 empty/NaN cells filled with the previous row's value" in _play(path, capsys)


def test_values_a_hair_outside_the_range(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "eps.csv", "frame,AU01,AU12\n0,-1e-7,1.0000001\n1,0.0,0.5\n")
    rec = load_recording(path)
    assert rec.frames[0].get("AU1") == 0.0 and rec.frames[0].get("AU12") == 1.0
    assert "2 values slightly outside their range clamped" in _play(path, capsys)


def test_tab_and_semicolon_separated(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tab = _write(tmp_path, "of.tsv", OF.replace(", ", "\t") + "\n" + _of_rows(3).replace(", ", "\t"))
    semi = _write(tmp_path, "bs.csv", "t;mouthSmileLeft;jawOpen\n0,0;0,25;0,1\n0,1;0,5;0,1\n")
    assert load_recording(tab).frames[0].get("AU12") == pytest.approx(0.5)
    assert "tab-separated" in _play(tab, capsys)
    rec = load_recording(semi)
    assert rec.duration_s == pytest.approx(0.1) and rec.frames[1].get("AU12L") == pytest.approx(0.5)
    assert "semicolon-separated, decimal comma" in _play(semi, capsys)


# -- accepted but played wrong before ----------------------------------------------------------------------
def test_openface_timestamps_in_milliseconds(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "ms.csv", OF + "\n" + _of_rows(30, step=33.3))
    rec = load_recording(path)
    assert rec.duration_s == pytest.approx(29 * 0.0333)  # not 966 s
    assert "timestamp in ms (detected: median step 33.3 = 30.03 fps" in _play(path, capsys)
    forced = load_recording(path, options=ReadOptions(time_unit="s"))
    assert forced.duration_s == pytest.approx(29 * 33.3)


def test_timestamps_stepping_one_millisecond(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "fast.csv", OF + "\n" + _of_rows(100, step=0.001))
    rec = load_recording(path)
    assert rec.duration_s == pytest.approx(99 / 30)  # timed by row at the default 30 fps, and said so
    out = _play(path, capsys, "--fps", "25")
    assert "no unit makes that a tracker's frame rate; rows timed at 25 fps" in out
    assert load_recording(path, options=ReadOptions(time_unit="s")).duration_s == pytest.approx(0.099)


def test_mediapipe_csv_without_times_takes_fps(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "mp_rows.csv", "eyeBlinkLeft,mouthSmileLeft\n" + "0.1,0.2\n" * 31)
    assert load_recording(path).duration_s == pytest.approx(0.5)  # default 60 fps, printed
    assert load_recording(path, fps=30.0).duration_s == pytest.approx(1.0)
    assert "no time column: rows timed at 30 fps (given)" in _play(path, capsys, "--fps", "30")


def test_pyfeat_two_faces_follow_one_person(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    head = "frame,FaceRectX,FaceRectY,FaceRectWidth,FaceRectHeight,FaceScore,AU12"
    rows = []
    for k in range(6):  # a big face on the left (AU12 0.6) and a small one on the right (AU12 0.0)
        rows.append(f"{k},{100 + k},100,200,200,0.99,0.6")
        rows.append(f"{k},{500 - k},120,80,80,0.98,0.0")
    path = _write(tmp_path, "two.csv", head + "\n" + "\n".join(rows) + "\n")
    rec = load_recording(path)
    assert [f.get("AU12") for f in rec.frames] == [0.6] * 6  # no 0 -> 0.6 -> 0 interleaving
    out = _play(path, capsys)
    assert "faces: up to 2 faces per frame (6 of 6 frames); followed one person" in out
    assert "skipped 6 x rows of other faces in the same frame" in out
    other = load_recording(path, options=ReadOptions(face_id=1))
    assert [f.get("AU12") for f in other.frames] == [0.0] * 6
    assert "followed face 1 (counted from the left)" in _play(path, capsys, "--face-id", "1")


def test_one_row_still_is_reached_and_held(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "still.csv", "frame,AU12,AU26\n0,0.9,0.4\n")
    trace = tmp_path / "trace.jsonl"
    rc = cli_main(["play", "--emulate", "--input", str(path), "--hold", "0.4", "--trace", str(trace)])
    out = capsys.readouterr().out
    assert rc == 0 and "one row: a still image (play holds it: --hold)" in out
    lines = [json.loads(line) for line in trace.read_text().splitlines()]
    assert lines[-1]["t_s"] >= 0.35  # held for 0.4 s (frames late on a loaded machine are skipped, not counted)
    assert all(line["aus"].get("AU12") == pytest.approx(0.9) for line in lines)


def test_fap_61_62_nose_stretch() -> None:
    aus = fap_to_aus({61: 64.0, 62: -64.0})
    assert aus["AU38L"] == pytest.approx(0.5) and aus["AU39R"] == pytest.approx(0.5)


# -- missing before --------------------------------------------------------------------------------------------
def test_mediapipe_resting_squint_and_blink_with_rest_pose(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rows = ["t,eyeSquintLeft,eyeSquintRight,eyeBlinkLeft,eyeBlinkRight,mouthSmileLeft"]
    for k in range(90):  # 1 s of neutral face (squint ~0.6, blink ~0.3), then a smile with a real blink
        t = k / 30
        blink = 1.0 if 60 <= k < 63 else 0.30 + 0.02 * math.sin(k)
        rows.append(f"{t:.4f},{0.6 + 0.03 * math.sin(k):.3f},0.62,{blink:.3f},0.3,{0.8 if k >= 45 else 0.0}")
    path = _write(tmp_path, "mp_rest.csv", "\n".join(rows) + "\n")
    raw = load_recording(path)
    assert raw.frames[10].get("AU43L") > 0.25  # straight through: half-shut eyes at rest
    rec = load_recording(path, options=ReadOptions(rest_s=1.0))
    rest = rec.frames[10]
    assert rest.get("AU43L") < 0.05 and rest.get("AU7L", 0.0) < 0.05
    assert rec.frames[61].get("AU43L") > 0.9 and rec.frames[50].get("AU12L") == pytest.approx(0.8)
    out = _play(path, capsys, "--rest-s", "1")
    assert "rest pose from the first 1 s (31 rows): eyeSquintRight 0.62" in out


def test_openface_head_pose_sign_convention(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    yaw, pitch, roll = openface_pose_deg(0.0, math.radians(20), 0.0)  # Ry > 0: turned to their own right
    assert yaw == pytest.approx(-20) and pitch == pytest.approx(0, abs=1e-9)
    yaw, pitch, roll = openface_pose_deg(math.radians(-10), 0.0, math.radians(5))  # Rx < 0: head tipped up
    assert pitch == pytest.approx(10, abs=0.1) and roll == pytest.approx(5, abs=0.1)
    head = "frame,timestamp,confidence,success,pose_Rx,pose_Ry,pose_Rz,AU12_r"
    path = _write(tmp_path, "pose.csv", head + "\n" + "".join(f"{k},{k / 30:.4f},0.9,1,0,0.35,0,1\n" for k in range(4)))
    rec = load_recording(path)
    assert rec.frames[0].get("AU52") > 0.4 and rec.frames[0].get("AU51") == 0.0  # AU52: head turns right
    assert load_recording(path, options=ReadOptions(mirror=True)).frames[0].get("AU51") > 0.4
    assert "AU52" not in load_recording(path, options=ReadOptions(head_pose=False)).frames[0].aus
    trace = tmp_path / "t.jsonl"
    _play(path, capsys, "--no-head-pose", "--trace", str(trace))
    assert all("AU52" not in json.loads(line)["aus"] for line in trace.read_text().splitlines())


def test_play_min_confidence_and_shape_ranges(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    of = _write(tmp_path, "conf.csv", OF + "\n1, 0, 0.0, 0.6, 1, 0.5, 2.5\n2, 0, 0.033, 0.95, 1, 0.5, 5\n")
    assert "1 filled by the lost-tracking policy" in _play(of, capsys)  # default gate 0.8
    assert "2 rows used" in _play(of, capsys, "--min-confidence", "0.5")
    ranges = _write(tmp_path, "ranges.json", json.dumps({"schema_version": 1, "ranges": {"mouthSmileLeft": [0, 0.5]}}))
    bs = _write(tmp_path, "bs.csv", "t,mouthSmileLeft\n0,0.25\n0.1,0.25\n")
    trace = tmp_path / "t.jsonl"
    _play(bs, capsys, "--shape-ranges", str(ranges), "--trace", str(trace))
    assert json.loads(trace.read_text().splitlines()[0])["aus"]["AU12L"] == pytest.approx(0.5)


def test_play_input_bad_options_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "x.csv", "frame,AU12\n0,0.5\n")
    for extra, named in ((["--fps", "0"], "--fps"), (["--min-confidence", "2"], "--min-confidence")):
        assert cli_main(["play", "--emulate", "--input", str(path), *extra]) == 2
        assert named in capsys.readouterr().err
    wrong = _write(tmp_path, "wrong.csv", "name,score\nx,1\n")
    assert cli_main(["play", "--emulate", "--input", str(wrong)]) == 2
    assert "cannot tell which tracker wrote this" in capsys.readouterr().err


def test_preview_input_prints_the_summary_and_renders(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, "cut.csv", OF + "\n" + _of_rows(5, au12=4.5) + "6, 0, 0.16")
    out_png = tmp_path / "still.png"
    rc = cli_main(["preview", "--input", str(path), "-o", str(out_png), "--size", "160x120", "--quiet"])
    out = capsys.readouterr().out
    assert rc == 0 and out_png.stat().st_size > 1000
    assert "OpenFace CSV: 5 rows used, 1 skipped" in out and "its most expressive frame" in out
