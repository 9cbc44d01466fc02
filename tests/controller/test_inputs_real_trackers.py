"""Readers against files as real trackers wrote them (tests/controller/fixtures/real_trackers/, sources in its
README): OpenFace 2.x and an older OpenFace, py-feat v1 and v2, Live Link Face at 60 fps and with 30 Hz rows,
a MediaPipe JS FaceLandmarkerResult. Each is read through the API (AUs, timing from the file's own
timestamps / frames / timecodes) and through `servoface play --input` / `preview --input`.

Three layouts are built here from their writers' code because no recording of them is public:
skellytracker's ``blendshapes_to_csv`` (a timecode in a ``Timestamp`` column, frames and seconds rolling over
at 30), OpenFace FaceLandmarkImg (``face, confidence, ...``: the faces of one image) and the pretty-printed /
array JSON dumps of the MediaPipe result. Their cell values are the real ones from the fixtures."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from servoface.controller.cli import main as cli_main
from servoface.controller.face import Face
from servoface.controller.inputs import InputError, ReadOptions, detect_format, load_recording
from servoface.controller.inputs.timecode import parse_timecode, timecode_seconds

from tests.controller.test_inputs_real_files import _play

FIX = Path(__file__).resolve().parent / "fixtures" / "real_trackers"
MEDIAPIPE_RESULT = FIX / "mediapipe_js_face_landmarker_result.json"

READERS = {
    "openface2_smile.csv": ("openface", "OpenFace CSV: 16 rows used"),
    "openface2_lost_tracking.csv": ("openface", "OpenFace CSV: 5 rows used, 5 filled by the lost-tracking policy"),
    "openface_legacy_image_sequence.csv": ("openface", "OpenFace CSV: 12 rows used"),
    "pyfeat_v1_video.csv": ("pyfeat", "py-feat CSV: 10 rows used"),
    "pyfeat_v2_news_video.csv": ("pyfeat", "py-feat CSV: 5 rows used"),
    "live_link_face_60fps.csv": ("blendshapes", "blendshape CSV: 6 rows used"),
    "live_link_face_30hz.csv": ("blendshapes", "blendshape CSV: 5 rows used"),
    "mediapipe_js_face_landmarker_result.json": ("jsonl", "JSON lines: 1 rows used"),
}


@pytest.fixture(scope="module", autouse=True)
def _warm_head() -> Iterator[None]:
    """Build the head's twin once before the CLI runs (the first build in a process is CPU-heavy and can starve
    the emulated chain's replies while `play` opens the bus)."""
    face = Face.open("human", emulate=True, wire_time=False)
    face.close(ease_s=0.0)
    yield


def _steps(path: Path, **options: object) -> list[float]:
    frames = load_recording(path, options=ReadOptions(**options)).frames  # type: ignore[arg-type]
    return [b.t_s - a.t_s for a, b in zip(frames, frames[1:], strict=False)]


# -- every fixture: detected, read, played ------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(READERS))
def test_every_real_file_is_detected_and_plays(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    kind, headline = READERS[name]
    assert detect_format(FIX / name) == kind
    out = _play(FIX / name, capsys)
    assert f"{name}: {headline}" in out


def test_preview_renders_the_real_openface_smile(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "smile.png"
    rc = cli_main(["preview", "--input", str(FIX / "openface2_smile.csv"), "-o", str(png), "--size", "160x120"])
    out = capsys.readouterr().out
    assert rc == 0 and png.stat().st_size > 1000
    assert "OpenFace CSV: 16 rows used" in out and "25 fps" in out


# -- OpenFace ----------------------------------------------------------------------------------------------
def test_openface2_smile_rises_with_the_files_25_fps_timestamps() -> None:
    rec = load_recording(FIX / "openface2_smile.csv")
    assert len(rec) == 16 and rec.report.fps == 25
    assert all(step == pytest.approx(0.04) for step in _steps(FIX / "openface2_smile.csv"))  # 1.560, 1.600 ...
    first, last = rec.frames[0], rec.frames[-1]
    assert first.get("AU12") == pytest.approx(1.63 / 5) and last.get("AU12") == pytest.approx(3.09 / 5)
    assert last.get("AU6") > 0.1  # cheek raiser with the smile (Duchenne)
    assert last.get("AU54") > 0.3 and last.get("AU64") > 0.5  # pose_Rx 0.29 rad: head down; gaze_angle_y 0.4: down
    assert "pose_Tx" in rec.report.columns_ignored and "AU12_c" not in rec.report.columns_ignored


def test_openface2_lost_rows_success_0_confidence_003() -> None:
    path = FIX / "openface2_lost_tracking.csv"
    held = load_recording(path)
    assert len(held) == 10 and held.report.held == 5
    assert all(f.aus == held.frames[4].aus for f in held.frames[5:])  # "hold": the last good row
    neutral = load_recording(path, options=ReadOptions(lost="neutral", decay_s=0.1))
    assert neutral.frames[-1].get("AU17") < 0.01 < held.frames[-1].get("AU17")
    lenient = load_recording(path, options=ReadOptions(min_confidence=0.0))
    assert lenient.report.held == 5  # success 0 still counts as lost


def test_openface_legacy_no_face_id_and_millisecond_timestamps(capsys: pytest.CaptureFixture[str]) -> None:
    """An older OpenFace (py-feat's test file): no face_id, header ", "-separated but rows ","-separated, and an
    image sequence stamped 0.001 s apart: no tracker runs at 1000 fps, so rows are timed at --fps."""
    path = FIX / "openface_legacy_image_sequence.csv"
    rec = load_recording(path)
    assert len(rec) == 12 and rec.duration_s == pytest.approx(11 / 30)
    assert rec.frames[0].get("AU1") == pytest.approx(0.6773 / 5)
    assert "no unit makes that a tracker's frame rate" in rec.report.time
    assert load_recording(path, fps=10.0).duration_s == pytest.approx(1.1)
    assert "rows timed at 30 fps instead" in _play(path, capsys)


def test_openface_face_landmark_img_faces_of_one_image(tmp_path: Path) -> None:
    """FaceLandmarkImg writes ``face, confidence, ...`` (OpenFace RecorderCSV, not a sequence): one row per face
    of one image. It was read as a 2-frame take; now one face is followed and the image is a still."""
    rows = (FIX / "openface2_smile.csv").read_text().splitlines()
    header, smile, other = rows[0].split(","), rows[-1].split(","), rows[1].split(",")
    keep = [i for i, h in enumerate(header) if h.strip() not in ("frame", "face_id", "timestamp", "success")]
    image = ["face, confidence" + ",".join(header[i] for i in keep[1:])]
    for face, cells in ((0, smile), (1, other)):
        image.append(f"{face}, 0.975" + ",".join(cells[i] for i in keep[1:]))
    path = tmp_path / "group_photo.csv"
    path.write_text("\n".join(image) + "\n")
    rec = load_recording(path)
    assert len(rec) == 1 and rec.frames[0].get("AU12") == pytest.approx(3.09 / 5)
    assert rec.report.faces.startswith("2 faces") and "one row: a still image" in " ".join(rec.report.notes)
    assert load_recording(path, options=ReadOptions(face_id=1)).frames[0].get("AU12") == pytest.approx(1.63 / 5)


# -- py-feat -----------------------------------------------------------------------------------------------
def test_pyfeat_v1_frame_column_last() -> None:
    rec = load_recording(FIX / "pyfeat_v1_video.csv")
    assert len(rec) == 10 and rec.duration_s == pytest.approx(9 / 30)
    assert rec.frames[0].get("AU12") == pytest.approx(0.50937, abs=1e-4) and rec.frames[0].get("AU6") > 0.3


def test_pyfeat_v2_skip_frames_and_blendshape_columns() -> None:
    """py-feat v2 writes AU01..AU43 and MediaPipe blendshape columns side by side; its frames step by 2
    (skip_frames) and ``approx_time`` is whole seconds only, so time = frame / fps."""
    path = FIX / "pyfeat_v2_news_video.csv"
    rec = load_recording(path)
    assert len(rec) == 5 and rec.duration_s == pytest.approx(8 / 30)  # frames 0, 2, 4, 6, 8
    assert all(f.get("AU12") > 0.99 for f in rec.frames)  # a news anchor's smile
    assert "AU12L" not in rec.frames[0].aus  # the AU columns are read, not the blendshape prior
    assert load_recording(path, fps=25.0).duration_s == pytest.approx(8 / 25)


# -- Live Link Face ----------------------------------------------------------------------------------------
def test_live_link_face_timecode_at_60_fps_across_a_second() -> None:
    path = FIX / "live_link_face_60fps.csv"
    rec = load_recording(path)
    assert rec.report.fps == pytest.approx(59.94, abs=0.01)  # 58.971 -> 59.972 -> 00.973: 1.001 frames a row
    assert all(step == pytest.approx(1.0005 / 60, abs=2e-5) for step in _steps(path))
    assert "frames at 60 fps (inferred: frames run to 59" in rec.report.time
    frame = rec.frames[0]
    assert frame.get("AU12L") > frame.get("AU12R") > 0.3  # MouthSmileLeft 0.53 > MouthSmileRight 0.41
    assert frame.get("AU26") > 0.5 or frame.get("AU27") > 0  # JawOpen 0.69
    assert "AU51" not in frame.aus  # HeadYaw/Pitch/Roll are ignored (all 0 in this take)
    assert any("HeadYaw" in n for n in rec.report.notes) and not any("BlendShapeCount" in n for n in rec.report.notes)
    forced = load_recording(path, fps=30.0)  # contradicts the file: said, and the rows that go back are skipped
    assert "the frame field reaches 59, not below the given 30 fps" in forced.report.time
    assert forced.report.skipped == {"time going back": 4}


def test_live_link_face_30hz_rows_on_a_60_fps_timecode(capsys: pytest.CaptureFixture[str]) -> None:
    path = FIX / "live_link_face_30hz.csv"
    rec = load_recording(path)
    assert len(rec) == 5 and rec.report.fps == pytest.approx(30.0, abs=0.01)  # frames 33, 35, 37 ... of 60
    assert rec.report.cells_clamped == 1  # EyeLookInRight 1.0033375025
    assert rec.frames[2].get("AU61") > 0.9  # right eye in, left eye out: looking to the subject's own left
    out = _play(path, capsys)
    assert "1 values slightly outside their range clamped" in out and "rows at 30 fps" in out


def test_live_link_face_as_excel_saves_it(tmp_path: Path) -> None:
    """The real take re-saved the way a European Excel writes CSV: BOM, CRLF, ';' and decimal commas."""
    text = (FIX / "live_link_face_60fps.csv").read_text()
    excel = "\r\n".join(
        ";".join(cell if ":" in cell else cell.replace(".", ",") for cell in line.split(","))
        for line in text.splitlines()
    )
    path = tmp_path / "take_excel.csv"
    path.write_bytes(b"\xef\xbb\xbf" + excel.encode() + b"\r\n")
    assert load_recording(path).frames == load_recording(FIX / "live_link_face_60fps.csv").frames


def test_frame_numbers_in_a_timecode_column(tmp_path: Path) -> None:
    """Some Live Link Face-style writers put frame numbers 1, 2, 3 ... in ``Timecode`` (described in
    WaterS-MoYu/Maya-Live-Link-CSV-Import's README); they were all "bad Timecode" rows, the file refused."""
    lines = (FIX / "live_link_face_60fps.csv").read_text().splitlines()
    numbered = [lines[0]] + [f"{k}{line[line.index(',') :]}" for k, line in enumerate(lines[1:], start=1)]
    path = tmp_path / "numbered.csv"
    path.write_text("\n".join(numbered) + "\n")
    rec = load_recording(path)
    assert len(rec) == 6 and rec.duration_s == pytest.approx(5 / 60) and "in frames at 60 fps" in rec.report.time
    assert load_recording(path, fps=30.0).duration_s == pytest.approx(5 / 30)


# -- skellytracker (MediaPipe blendshapes written as a Live Link Face-like CSV) -------------------------------
def _skellytracker_csv(path: Path, rows: int) -> None:
    """What freemocap skellytracker's scripts/blendshapes_to_csv.py writes: a ``Timestamp`` column of
    ``HH:MM:SS:FF.nnn`` whose every field rolls over at 30 (count from 1; ``.nnn`` = count % 1000),
    ``BlendShapeCount`` 52, then the 51 MediaPipe shapes (``_neutral`` dropped). Scores: the real result."""
    result = json.loads(MEDIAPIPE_RESULT.read_text())
    shapes = [(c["categoryName"], c["score"]) for c in result["faceBlendshapes"][0]["categories"]][1:]
    lines = ["Timestamp,BlendShapeCount," + ",".join(name for name, _ in shapes)]
    for count in range(1, rows + 1):
        parts = [(count // 30**i) % 30 for i in range(4)]
        stamp = f"{parts[3]:02d}:{parts[2]:02d}:{parts[1]:02d}:{parts[0]:02d}.{count % 1000:03d}"
        smile = 0.8 if count % 30 < 15 else 0.1
        cells = [f"{smile if name == 'mouthSmileLeft' else score}" for name, score in shapes]
        lines.append(f"{stamp},52," + ",".join(cells))
    path.write_text("\n".join(lines) + "\n")


def test_skellytracker_timestamp_column_holding_a_30_fps_timecode(tmp_path: Path) -> None:
    path = tmp_path / "skelly_blendshapes.csv"
    _skellytracker_csv(path, 40)
    rec = load_recording(path)  # refused before: every "Timestamp" cell was "text in Timestamp"
    assert len(rec) == 40 and rec.report.fps == pytest.approx(30, abs=0.1)
    assert rec.duration_s == pytest.approx(39 / 30 * 1.001, abs=1e-3)  # .nnn read as a fraction of a frame
    assert "frames at 30 fps (inferred: frames run to 29" in rec.report.time
    assert rec.sample(0.2).get("AU12L") > 0.7 and rec.sample(0.7).get("AU12L") < 0.2


def test_skellytracker_seconds_rolling_over_at_30(tmp_path: Path) -> None:
    path = tmp_path / "skelly_long.csv"
    _skellytracker_csv(path, 30 * 30 + 10)  # 00:00:29:29 is followed by 00:01:00:00
    rec = load_recording(path)
    steps = [b.t_s - a.t_s for a, b in zip(rec.frames, rec.frames[1:], strict=False)]
    assert max(steps) < 0.05 and rec.duration_s == pytest.approx(909 / 30, abs=0.05)
    assert "roll over at 30" in rec.report.time


# -- MediaPipe JS result --------------------------------------------------------------------------------------
def test_mediapipe_js_result_one_line() -> None:
    rec = load_recording(MEDIAPIPE_RESULT)
    frame = rec.frames[0]
    assert frame.get("AU12R") == pytest.approx(0.0326, abs=1e-3) and frame.get("AU12L") > 0.02  # mouthSmile*
    assert frame.get("AU43L") == pytest.approx(0.151, abs=1e-3)  # eyeBlinkLeft 0.15118
    assert not {"AU51", "AU52", "AU53", "AU54"} & set(frame.aus)  # empty transformation matrixes: no head pose


def test_mediapipe_js_result_pretty_printed_and_as_an_array(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The result as its source shows it (JSON.stringify(result, null, 4)): one object over 300 lines was 300
    "lines that are not JSON"; an array of results was "cannot tell which tracker"."""
    result = json.loads(MEDIAPIPE_RESULT.read_text())
    one = load_recording(MEDIAPIPE_RESULT).frames[0]
    pretty = tmp_path / "result.json"
    pretty.write_text(json.dumps(result, indent=4) + "\n")
    assert detect_format(pretty) == "jsonl" and load_recording(pretty).frames[0].aus == one.aus
    stream = tmp_path / "results_appended.json"
    stream.write_text("".join(json.dumps({**result, "timestamp_ms": 40 * k}, indent=2) + "\n" for k in range(3)))
    assert load_recording(stream).duration_s == pytest.approx(0.08)
    array = tmp_path / "results.json"
    array.write_text(json.dumps([result, result], indent=2))
    rec = load_recording(array)
    assert detect_format(array) == "jsonl" and len(rec) == 2 and rec.duration_s == pytest.approx(1 / 60)
    assert "JSON lines: 2 rows used" in _play(array, capsys)


def test_broken_json_names_the_line_and_what_was_expected(tmp_path: Path) -> None:
    result = json.loads(MEDIAPIPE_RESULT.read_text())
    text = json.dumps([result, result], indent=2)
    cut = tmp_path / "cut.json"
    cut.write_text(text[: len(text) // 2 + 40] + "\n]")  # a dump stopped mid-write
    with pytest.raises(
        InputError, match=r"cut\.json: line \d+: not valid JSON in the array: .*\(line \d+, column \d+\)"
    ):
        load_recording(cut)
    torn = tmp_path / "torn.jsonl"
    line = json.dumps(result)
    torn.write_text(f"{line}\n{line[:200]}\n{line}\n")
    rec = load_recording(torn)
    assert len(rec) == 2 and rec.report.skipped == {"lines that are not JSON": 1}
    with pytest.raises(InputError, match=r"torn\.jsonl: line 2: not valid JSON"):
        load_recording(torn, options=ReadOptions(bad_rows="error"))


# -- timecode cells that are truly bad ---------------------------------------------------------------------
def test_bad_timecode_cells_name_line_column_and_form(tmp_path: Path) -> None:
    lines = (FIX / "live_link_face_60fps.csv").read_text().splitlines()
    lines[3] = "00:32:12" + lines[3][len("00:32:12:00.973") :]  # frames missing
    path = tmp_path / "bad_tc.csv"
    path.write_text("\n".join(lines) + "\n")
    assert load_recording(path).report.skipped == {"bad timecode": 1}
    with pytest.raises(InputError, match=r"line 4, column 'Timecode' \(#1\): '00:32:12' is not a timecode HH:MM:SS:FF"):
        load_recording(path, options=ReadOptions(bad_rows="error"))
    with pytest.raises(InputError, match="minutes and seconds must be 0..59"):
        parse_timecode("00:61:00:00", "x")


def test_timecode_across_midnight_keeps_counting() -> None:
    codes = [parse_timecode(t, "x") for t in ("23:59:59:58.000", "23:59:59:59.000", "00:00:00:00.000")]
    seconds, note = timecode_seconds(codes, None)
    assert [round(b - a, 4) for a, b in zip(seconds, seconds[1:], strict=False)] == [round(1 / 60, 4)] * 2
    assert "60 fps" in note and math.isfinite(seconds[-1])
