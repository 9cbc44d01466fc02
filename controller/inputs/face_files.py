"""Recorded blendshape / AU files -> a Recording: JSON lines (one message per line, messages.py, or one
MediaPipe result per line, mediapipe_result.py) and blendshape CSVs (ARKit / MediaPipe names as columns; Live
Link Face's CSV export included).

JSON lines: every line is a message object with a time ``t`` (s) or ``timestamp_ms``; a file without any
times is timed by row at ``fps`` (default 60, reported). Blank lines and lines starting with ``#`` are
skipped. A bad line is a bad row (tolerance.py); errors name the file, the line and the field (``aus.AU12``).
Pretty-printed objects one after another and one JSON array of objects are read the same way, each object
named by the line it starts on (json_stream.py).

Blendshape CSV: one column per blendshape (ARKit spelling, or Live Link Face's ``EyeBlinkLeft`` /
``EYE_BLINK_LEFT``), a time column ``t`` / ``t_s`` / ``time`` / ``timestamp`` / ``timestamp_ms`` (unit
detected, timebase.py) or ``frame``, or a timecode ``HH:MM:SS:FF[.sub]`` in ``Timecode`` or any time column
(skellytracker writes it in ``Timestamp``; frame rate given or inferred, timecode.py; plain numbers in a
``Timecode`` column are frame numbers at ``fps``), or none (rows at ``fps``, default 60); optional
``yaw_deg, pitch_deg, roll_deg`` (head_pose.py convention) and ``confidence``. Live Link Face's
``BlendShapeCount`` and head/eye rotation columns (units not documented; any spelling) and any other unknown
column are ignored and listed in the report.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from servoface.controller.frame import check_face_type
from servoface.controller.inputs.assemble import RawRow, ReadOptions, assemble, fill_cells
from servoface.controller.inputs.blendshapes import SCORE_SLACK, _fold
from servoface.controller.inputs.csv_table import CsvTable, read_text
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.head_pose import parse_head
from servoface.controller.inputs.json_stream import json_items
from servoface.controller.inputs.mediapipe_result import NoFace, is_result, normalise_result
from servoface.controller.inputs.messages import MessageDecoder
from servoface.controller.inputs.openface import _options
from servoface.controller.inputs.recorded import Recording
from servoface.controller.inputs.report import InputReport
from servoface.controller.inputs.timecode import Timecode, looks_like_timecode, parse_timecode, timecode_seconds
from servoface.controller.inputs.tolerance import BadRow, Tolerance
from servoface.sim.rig import FaceType

_TIME_COLUMNS = ("t", "t_s", "time", "timestamp", "timestamp_s", "timestamp_ms", "timestamp_us", "frame", "timecode")
_POSE_COLUMNS = ("yaw_deg", "pitch_deg", "roll_deg")
_LLF_ROTATIONS = frozenset(
    _fold(n)
    for n in (
        "HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll",
        "RightEyeYaw", "RightEyePitch", "RightEyeRoll",
    )
)  # fmt: skip


def read_jsonl(
    path: str | Path,
    face_type: FaceType = "human",
    *,
    options: ReadOptions | None = None,
    mirror: bool | None = None,
    min_confidence: float | None = None,
    lost: str | None = None,
    decay_s: float | None = None,
    interpolate: bool | None = None,
    bad_rows: str | None = None,
) -> Recording:
    """Read a JSON-lines file of messages (or MediaPipe results) into a Recording."""
    opts = _options(
        options, mirror=mirror, min_confidence=min_confidence, lost=lost, decay_s=decay_s,
        interpolate=interpolate, bad_rows=bad_rows,
    )  # fmt: skip
    file = Path(path)
    kind_face = check_face_type(face_type)
    report = InputReport(str(file), reader="JSON lines")
    tol = Tolerance(report, opts.bad_rows)
    decoder = MessageDecoder(kind_face)
    gate = opts.min_confidence or 0.0
    rows: list[RawRow] = []
    timed: list[bool] = []
    total = 0
    clamped: list[str] = []
    for number, obj in json_items(read_text(file), str(file)):
        total += 1
        where = f"{file}: line {number}"
        try:
            if isinstance(obj, BadRow):
                raise obj
            row, has_t = _jsonl_row(obj, number, where, decoder, opts, gate, clamped)
        except BadRow as err:
            tol.handle(err)
            continue
        rows.append(row)
        timed.append(has_t)
    report.cells_clamped += len(clamped)
    if not total:
        raise InputError(f"{file}: no messages")
    if any(timed) and not all(timed):
        first = next(r.line for r, has in zip(rows, timed, strict=True) if not has)
        raise InputError(f"{file}: line {first}.t: missing; the other lines have a time t (s), every line needs one")
    kind = "blendshapes" if kind_face == "human" else "aus"
    return assemble(
        rows, report, opts, tol, kind=kind, time_column="t" if all(timed) and rows else None,
        default_fps=60.0, face_type=kind_face, total_rows=total,
    )  # fmt: skip


def _jsonl_row(
    obj: Any,
    number: int,
    where: str,
    decoder: MessageDecoder,
    opts: ReadOptions,
    gate: float,
    clamped: list[str],
) -> tuple[RawRow, bool]:
    try:
        if is_result(obj):
            obj = normalise_result(obj, face_id=opts.face_id or 0, where=where)
    except NoFace:
        t = obj.get("timestamp_ms") if isinstance(obj, dict) else None
        return RawRow(number, float(t) / 1e3 if isinstance(t, int | float) else float(number), None), t is not None
    except InputError as err:
        raise BadRow(str(err), "malformed MediaPipe results") from err
    try:
        if not isinstance(obj, dict):
            raise InputError(f"{where}: expected a JSON object, got {type(obj).__name__}")
        msg = decoder.decode(obj, where=where)  # validates every field; a recording's t is checked by the caller
        if decoder.face_type != "human":
            values: dict[str, float] | None = dict(msg.aus)
            extra: dict[str, float] = {}
            head = None
        else:
            bmap = decoder.blendshape_map
            shapes = obj.get("blendshapes") or {}
            if not isinstance(shapes, dict):
                raise InputError(f"{where}.blendshapes: expected an object of name -> score")
            values = {}
            for raw, score in shapes.items():
                name = bmap.resolve(raw, field=f"{where}.blendshapes.{raw}")
                values[name] = _score(score, f"{where}.blendshapes.{raw}", clamped)
            extra = decoder.validator.pose(obj["aus"], where=f"{where}.aus") if "aus" in obj else {}
            head = parse_head(obj["head"], field=f"{where}.head") if "head" in obj else None
    except InputError as err:
        raise BadRow(str(err), "messages with a bad field") from err
    except Exception as err:  # FrameError from the validator
        raise BadRow(f"{where}: {err}", "messages with a bad field") from err
    t = msg.t_s if msg.t_s is not None else float(number)
    if msg.confidence < gate:
        return RawRow(number, t, None), msg.t_s is not None
    return RawRow(number, t, values, head, None, extra), msg.t_s is not None


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _score(value: Any, field: str, clamped: list[str]) -> float:
    from servoface.controller.inputs.blendshapes import check_score

    return check_score(value, field=field, clamped=clamped)


def read_blendshape_csv(
    path: str | Path,
    *,
    options: ReadOptions | None = None,
    fps: float | None = None,
    mirror: bool | None = None,
    min_confidence: float | None = None,
    lost: str | None = None,
    decay_s: float | None = None,
    interpolate: bool | None = None,
    bad_rows: str | None = None,
) -> Recording:
    """Read a blendshape CSV into a human Recording (see the module doc for the columns)."""
    opts = _options(
        options, fps=fps, mirror=mirror, min_confidence=min_confidence, lost=lost, decay_s=decay_s,
        interpolate=interpolate, bad_rows=bad_rows,
    )  # fmt: skip
    report = InputReport(str(path), reader="blendshape CSV")
    tol = Tolerance(report, opts.bad_rows)
    table = CsvTable(path, report=report, tolerance=tol)
    bmap = MessageDecoder("human").blendshape_map
    by_fold = {c.lower(): c for c in table.header}
    time_col = next((by_fold[c] for c in _TIME_COLUMNS if c in by_fold), None)
    conf_col = by_fold.get("confidence")
    pose_cols = [by_fold.get(c) for c in _POSE_COLUMNS]
    shape_cols: dict[str, str] = {}
    for column in table.header:
        if column in (time_col, conf_col, *pose_cols):
            continue
        try:
            shape_cols[column] = bmap.resolve(column, field=column)
        except InputError:
            report.columns_ignored.append(column)
    if not shape_cols:
        raise InputError(
            f"{table.path}: no blendshape columns found (expected ARKit/MediaPipe names such as mouthSmileLeft); "
            f"header has {', '.join(table.header[:8])}"
        )
    llf = [c for c in report.columns_ignored if _fold(c) in _LLF_ROTATIONS]
    if llf:
        report.notes.append(f"Live Link Face head/eye rotation columns ignored (units undocumented): {llf[:4]}")
    is_timecode: bool | None = None  # decided by the first data row (skellytracker's "Timestamp" holds one)
    codes: list[Timecode] = []
    rows: list[RawRow] = []
    last: dict[str, float] = {}
    total = 0
    for line, cells in table.rows():
        total += 1
        try:
            if time_col is None:
                t = float(len(rows))
            else:
                text = table.cell(cells, line, time_col)
                if is_timecode is None:
                    named = time_col.lower() == "timecode"
                    is_timecode = looks_like_timecode(text) or (named and not _is_number(text))
                if is_timecode:
                    code = parse_timecode(text, table.where(line, time_col))
                    t = float(len(rows))
                else:
                    t = table.number(cells, line, time_col)
            values: dict[str, float] = {}
            for col, name in shape_cols.items():
                raw = table.value(cells, line, col)
                where = table.where(line, col)
                values[name] = raw if math.isnan(raw) else tol.ranged(raw, 0.0, 1.0, where=where, what="a score")
            head = None
            if any(pose_cols):
                ypr = [table.number(cells, line, c) if c else 0.0 for c in pose_cols]
                for c, v in zip(pose_cols, ypr, strict=True):
                    if c and abs(v) > 180:
                        raise BadRow(f"{table.where(line, c)}: {v:g} deg is outside ±180", "head angles beyond ±180")
                head = (ypr[0], ypr[1], ypr[2])
            confidence = table.number(cells, line, conf_col) if conf_col else 1.0
        except BadRow as err:
            tol.handle(err)
            continue
        good = confidence >= (opts.min_confidence or 0.0)
        filled = fill_cells(values, last, report) if good else None
        rows.append(RawRow(line, t, filled, head if filled is not None else None))
        if is_timecode:
            codes.append(code)
    timecode_note = ""
    if not is_timecode and time_col is not None and time_col.lower() == "timecode" and opts.time_unit == "auto":
        opts = _options(opts, time_unit="frames")  # frame numbers in a Timecode column (some LLF-style writers)
    if is_timecode:
        seconds, timecode_note = timecode_seconds(codes, opts.fps)
        rows = [replace(row, t=t_s) for row, t_s in zip(rows, seconds, strict=True)]
        opts = _options(opts, time_unit="s" if opts.time_unit == "auto" else None)
    recording = assemble(
        rows, report, opts, tol, kind="blendshapes", time_column=time_col, default_fps=60.0, total_rows=total
    )
    if timecode_note:
        report.time = f"{time_col}: {timecode_note}" + (f"; rows at {report.fps:g} fps" if report.fps else "")
    return recording


__all__ = ["SCORE_SLACK", "read_blendshape_csv", "read_jsonl"]
