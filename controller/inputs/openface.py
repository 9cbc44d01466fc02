"""OpenFace 2.x (FeatureExtraction / FaceLandmarkVidMulti) and py-feat CSV files -> a Recording of AU frames.

OpenFace (facs-human.md §5): columns are found by header name, stripped of the leading spaces some builds
write (``frame, face_id, timestamp, confidence, success, ..., AU01_r ... AU45_r, AU01_c ...``); extra
columns are ignored. Required: ``timestamp``, ``confidence``, ``success`` and at least one ``AUxx_r``.
Intensities 0..5 become 0..1 (``/ 5``, clamped; a value beyond -0.5..5.5 is an error: wrong column or
file). Presence columns ``_c`` are not used. With several faces (``face_id``), one face is read (default:
the lowest id).

Lost tracking: a row with ``success == 0`` or ``confidence < min_confidence`` (default 0.8, the common
gate) is not trusted; the ``lost`` policy fills it: ``"hold"`` (default) keeps the last good AUs,
``"neutral"`` eases them to neutral over ``decay_s``.

Gaze (opt-in, ``gaze=True``): ``gaze_angle_x`` / ``gaze_angle_y`` (rad, both eyes averaged) become AU61-64.
Per the OpenFace wiki ("Output Format"), looking left to right takes gaze_angle_x from positive to negative
and looking up to down takes gaze_angle_y from negative to positive; servoface reads + x as the subject's
own left and + y as down. Head pose (``pose_R*``) is not mapped: its sign convention is not on the
reference sheet. Frames from a file are not smoothed (the samples are
the recording); smooth live data with the stream source.

py-feat (§6): columns ``AU01 ... AU43`` (roughly 0..1), optional ``frame`` and ``FaceScore``; py-feat
writes no timestamp, so ``t = frame / fps``. A row whose AU cells are all empty/NaN is "no face" (lost);
a row with some AU cells missing is an error.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from servoface.controller.au_names import canonical_au, default_au_names
from servoface.controller.inputs.csv_table import CsvTable
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.head_pose import eye_angles_aus
from servoface.controller.inputs.recorded import InputReport, Recording, frames_with_policy
from servoface.controller.inputs.sides import mirror_aus

_OPENFACE_AU = re.compile(r"^AU(\d{2})_r$")
_PYFEAT_AU = re.compile(r"^AU(\d{2})$")


def _au_columns(table: CsvTable, pattern: re.Pattern[str], allowed: frozenset[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for column in table.header:
        match = pattern.match(column)
        if match:
            name = canonical_au(f"AU{match.group(1)}", field=f"{table.path}: column {column!r}")
            if name in allowed:
                out[column] = name
    if not out:
        raise InputError(
            f"{table.path}: no AU intensity columns found (expected e.g. "
            f"{'AU12_r' if pattern is _OPENFACE_AU else 'AU12'})"
        )
    return out


def read_openface_csv(
    path: str | Path,
    *,
    min_confidence: float = 0.8,
    lost: str = "hold",
    decay_s: float = 0.5,
    face_id: int | None = None,
    mirror: bool = False,
    interpolate: bool = True,
    gaze: bool = False,
) -> Recording:
    """Read an OpenFace 2.x CSV into a human Recording (see the module doc for the policy)."""
    table = CsvTable(path)
    table.require("timestamp", "confidence", "success")
    if gaze:
        table.require("gaze_angle_x", "gaze_angle_y")
    allowed = default_au_names("human")
    au_cols = _au_columns(table, _OPENFACE_AU, allowed)
    report = InputReport(str(table.path))
    rows: list[tuple[float, dict[str, float] | None]] = []
    wanted = face_id
    last_t = -float("inf")
    skipped_faces = clamped = 0
    for line, cells in table.rows():
        if "face_id" in table.columns:
            fid = int(table.number(cells, line, "face_id"))
            if wanted is None:
                wanted = fid
            if fid != wanted:
                skipped_faces += 1
                continue
        t_s = table.number(cells, line, "timestamp")
        if t_s < last_t:
            raise InputError(
                f"{table.where(line, 'timestamp')}: {t_s:g} s is earlier than the row before "
                f"({last_t:g} s); timestamps must not decrease"
            )
        last_t = t_s
        confidence = table.number(cells, line, "confidence")
        success = table.number(cells, line, "success")
        if success not in (0.0, 1.0):
            raise InputError(f"{table.where(line, 'success')}: expected 0 or 1, got {success:g}")
        aus: dict[str, float] = {}
        for column, name in au_cols.items():
            raw = table.number(cells, line, column)
            if not -0.5 <= raw <= 5.5:
                raise InputError(f"{table.where(line, column)}: intensity {raw:g} is outside OpenFace's 0..5")
            value = min(1.0, max(0.0, raw / 5.0))
            clamped += value != raw / 5.0
            aus[name] = value
        if gaze:
            yaw_rad, down_rad = (table.number(cells, line, c) for c in ("gaze_angle_x", "gaze_angle_y"))
            aus.update(eye_angles_aus(math.degrees(yaw_rad), -math.degrees(down_rad)))
        report.rows += 1
        good = success == 1.0 and confidence >= min_confidence
        rows.append((t_s, (mirror_aus(aus, "human") if mirror else aus) if good else None))
    if not rows:
        raise InputError(f"{table.path}: no data rows" + (f" for face_id {wanted}" if wanted is not None else ""))
    frames, report.held = frames_with_policy(rows, "human", lost=lost, decay_s=decay_s)
    if skipped_faces:
        report.notes.append(f"{skipped_faces} rows of other faces skipped (read face_id {wanted})")
    if clamped:
        report.notes.append(f"{clamped} intensities slightly outside 0..5 clamped")
    if report.held:
        report.notes.append(
            f"{report.held} rows with success=0 or confidence < {min_confidence:g} filled by policy {lost!r}"
        )
    return Recording(frames, "human", interpolate=interpolate, source=str(table.path), report=report)


def read_pyfeat_csv(
    path: str | Path,
    *,
    fps: float = 30.0,
    min_confidence: float = 0.5,
    lost: str = "hold",
    decay_s: float = 0.5,
    mirror: bool = False,
    interpolate: bool = True,
) -> Recording:
    """Read a py-feat ``Fex`` CSV (AU01..AU43 columns) into a human Recording; ``t = frame / fps``."""
    if not (isinstance(fps, int | float) and 0 < fps <= 10_000):
        raise InputError(f"fps: expected a frame rate 0 < fps <= 10000, got {fps!r}")
    table = CsvTable(path)
    allowed = default_au_names("human")
    au_cols = _au_columns(table, _PYFEAT_AU, allowed)
    report = InputReport(str(table.path))
    rows: list[tuple[float, dict[str, float] | None]] = []
    for index, (line, cells) in enumerate(table.rows()):
        frame = table.number(cells, line, "frame") if "frame" in table.columns else float(index)
        score = table.number(cells, line, "FaceScore", allow_empty=True) if "FaceScore" in table.columns else 1.0
        values = {col: table.number(cells, line, col, allow_empty=True) for col in au_cols}
        missing = [c for c, v in values.items() if v != v]
        report.rows += 1
        if len(missing) == len(values) or (score == score and score < min_confidence):
            rows.append((frame / fps, None))
            continue
        if missing:
            raise InputError(f"{table.where(line, missing[0])}: empty/NaN while other AUs of the row are set")
        aus: dict[str, float] = {}
        for column, value in values.items():
            if not -0.05 <= value <= 1.05:
                raise InputError(f"{table.where(line, column)}: {value:g} is outside py-feat's 0..1")
            aus[au_cols[column]] = min(1.0, max(0.0, value))
        rows.append((frame / fps, mirror_aus(aus, "human") if mirror else aus))
    if not rows:
        raise InputError(f"{table.path}: no data rows")
    frames, report.held = frames_with_policy(rows, "human", lost=lost, decay_s=decay_s)
    return Recording(frames, "human", interpolate=interpolate, source=str(table.path), report=report)
