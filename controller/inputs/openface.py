"""OpenFace 2.x (FeatureExtraction / FaceLandmarkVidMulti) and py-feat CSV files -> a Recording of AU frames.

OpenFace (facs-human.md §5): columns are found by header name, stripped of the leading spaces some builds
write (``frame, face_id, timestamp, confidence, success, ..., AU01_r ... AU45_r, AU01_c ...``); extra
columns are ignored. Needed: at least one ``AUxx_r``; ``timestamp`` (unit detected, timebase.py; else
``frame`` at fps, else row order), ``confidence`` and ``success`` are used when present (a file trimmed to
its AU columns is read as all tracked, with a note). Intensities 0..5 become 0..1 (``/ 5``; a value up to
0.5 beyond 0..5 is clamped and counted, beyond that the row is bad, tolerance.py). Presence columns ``_c``
are not used. With several faces (``face_id``), one face is read (default: the lowest id). FaceLandmarkImg
writes an image's faces as ``face, confidence, ...`` (no frame, timestamp or success): ``face`` is read as the
face id, and one face of one image is a still.

Lost tracking: a row with ``success == 0`` or ``confidence < min_confidence`` (default 0.8, the common
gate) is not trusted; the ``lost`` policy fills it: ``"hold"`` (default) keeps the last good AUs,
``"neutral"`` eases them to neutral over ``decay_s``.

Gaze (``gaze``, on by default when the columns are there): ``gaze_angle_x`` / ``gaze_angle_y`` (rad, both eyes
averaged) become AU61-64. Per the OpenFace wiki, looking left to right takes gaze_angle_x from positive to
negative and looking up to down takes gaze_angle_y from negative to positive; servoface reads + x as the
subject's own left and + y as down. Head pose (``head_pose``, on when ``pose_Rx/Ry/Rz`` are there): see
:func:`servoface.controller.inputs.head_pose.openface_pose_deg` for the sign convention. Frames from a file
are not smoothed (the samples are the recording).

py-feat (§6): columns ``AU01 ... AU43`` (roughly 0..1), optional ``frame`` and ``FaceScore``; py-feat
writes no timestamp, so ``t = frame / fps``. Several rows with one ``frame`` are several faces: one person
is followed (faces.py). A row whose AU cells are all empty/NaN is "no face" (lost); single empty cells are
filled (tolerance.py).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from servoface.controller.au_names import canonical_au, default_au_names
from servoface.controller.inputs.assemble import RawRow, ReadOptions, assemble, fill_cells
from servoface.controller.inputs.csv_table import CsvTable
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.faces import FaceBox, FaceFollower
from servoface.controller.inputs.head_pose import openface_pose_deg
from servoface.controller.inputs.recorded import Recording
from servoface.controller.inputs.report import InputReport
from servoface.controller.inputs.tolerance import BadRow, Tolerance

_OPENFACE_AU = re.compile(r"^AU(\d{2})_r$")
_PYFEAT_AU = re.compile(r"^AU(\d{2})$")
_POSE = ("pose_Rx", "pose_Ry", "pose_Rz")
_BOX = ("FaceRectX", "FaceRectY", "FaceRectWidth", "FaceRectHeight")


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


def _options(options: ReadOptions | None, **given: object) -> ReadOptions:
    base = options or ReadOptions()
    changes = {k: v for k, v in given.items() if v is not None}
    return ReadOptions(**{**base.__dict__, **changes})


def read_openface_csv(
    path: str | Path,
    *,
    options: ReadOptions | None = None,
    min_confidence: float | None = None,
    lost: str | None = None,
    decay_s: float | None = None,
    face_id: int | None = None,
    mirror: bool | None = None,
    interpolate: bool | None = None,
    gaze: bool | None = None,
    head_pose: bool | None = None,
    bad_rows: str | None = None,
) -> Recording:
    """Read an OpenFace 2.x CSV into a human Recording (see the module doc for the policy)."""
    opts = _options(
        options, min_confidence=min_confidence, lost=lost, decay_s=decay_s, face_id=face_id, mirror=mirror,
        interpolate=interpolate, gaze=gaze, head_pose=head_pose, bad_rows=bad_rows,
    )  # fmt: skip
    gate = 0.8 if opts.min_confidence is None else opts.min_confidence
    report = InputReport(str(path), reader="OpenFace CSV")
    tol = Tolerance(report, opts.bad_rows)
    table = CsvTable(path, report=report, tolerance=tol)
    au_cols = _au_columns(table, _OPENFACE_AU, default_au_names("human"))
    missing = [c for c in ("confidence", "success") if c not in table.columns]
    if missing:
        report.notes.append(f"no {' / '.join(missing)} column: every row read as tracked")
    time_col = next((c for c in ("timestamp", "frame") if c in table.columns), None)
    has_pose = all(c in table.columns for c in _POSE)
    has_gaze = all(c in table.columns for c in ("gaze_angle_x", "gaze_angle_y"))
    face_col = next((c for c in ("face_id", "face") if c in table.columns), None)
    used = set(au_cols) | {"face_id", "face", "timestamp", "frame", "confidence", "success"}
    used |= set(_POSE) if has_pose else set()
    used |= {"gaze_angle_x", "gaze_angle_y"} if has_gaze else set()
    report.columns_ignored = [c for c in table.header if c not in used and not c.endswith("_c")]
    if len(report.columns_ignored) > 20:  # a full OpenFace file: landmarks, shape parameters ...
        report.columns_ignored = [f"{len(report.columns_ignored)} landmark/shape/eye columns"]
    rows: list[RawRow] = []
    faces: dict[int, int] = {}
    wanted = opts.face_id
    last: dict[str, float] = {}
    total = 0
    for line, cells in table.rows():
        total += 1
        try:
            if face_col is not None:
                fid = int(table.number(cells, line, face_col))
                faces[fid] = faces.get(fid, 0) + 1
                if wanted is None:
                    wanted = min(faces)
                if fid != wanted:
                    continue
            t = table.number(cells, line, time_col) if time_col else float(len(rows))
            confidence = table.number(cells, line, "confidence") if "confidence" in table.columns else 1.0
            success = table.number(cells, line, "success") if "success" in table.columns else 1.0
            if success not in (0.0, 1.0):
                raise BadRow(f"{table.where(line, 'success')}: expected 0 or 1, got {success:g}", "success not 0/1")
            values: dict[str, float] = {}
            for column, name in au_cols.items():
                raw = table.value(cells, line, column)
                if math.isnan(raw):
                    values[name] = raw
                    continue
                values[name] = tol.ranged(raw, 0.0, 5.0, where=table.where(line, column), what="OpenFace's") / 5.0
            head: tuple[float, float, float] | None = None
            gaze_deg: tuple[float, float] | None = None
            if has_pose:
                rot = [table.value(cells, line, c) for c in _POSE]
                if not any(math.isnan(v) for v in rot):
                    head = openface_pose_deg(*rot)
            if has_gaze:
                gx, gy = (table.value(cells, line, c) for c in ("gaze_angle_x", "gaze_angle_y"))
                if not (math.isnan(gx) or math.isnan(gy)):
                    gaze_deg = (math.degrees(gx), -math.degrees(gy))
        except BadRow as err:
            tol.handle(err)
            continue
        good = success == 1.0 and confidence >= gate
        filled = fill_cells(values, last, report) if good else None
        rows.append(RawRow(line, t, filled, head if good else None, gaze_deg if good else None))
    if len(faces) > 1:
        shown = ", ".join(f"{k} ({n} rows)" for k, n in sorted(faces.items()))
        report.faces = f"{len(faces)} faces: face_id {shown}; followed face_id {wanted} (--face-id)"
        report.skip(f"rows of other faces than face_id {wanted}", sum(n for k, n in faces.items() if k != wanted))
    if wanted is not None and faces and wanted not in faces:
        raise InputError(f"{table.path}: no rows for face_id {wanted}; the file has face_id {sorted(faces)}")
    recording = assemble(rows, report, opts, tol, kind="aus", time_column=time_col, default_fps=30.0, total_rows=total)
    if report.held:
        report.notes.append(f"lost tracking = success 0 or confidence < {gate:g} (--min-confidence)")
    if len(rows) == 1:
        report.notes.append("one row: a still image (play holds it: --hold)")
    return recording


def read_pyfeat_csv(
    path: str | Path,
    *,
    options: ReadOptions | None = None,
    fps: float | None = None,
    min_confidence: float | None = None,
    lost: str | None = None,
    decay_s: float | None = None,
    mirror: bool | None = None,
    interpolate: bool | None = None,
    face_id: int | None = None,
    bad_rows: str | None = None,
) -> Recording:
    """Read a py-feat ``Fex`` CSV (AU01..AU43 columns) into a human Recording; ``t = frame / fps``."""
    opts = _options(
        options, fps=fps, min_confidence=min_confidence, lost=lost, decay_s=decay_s, mirror=mirror,
        interpolate=interpolate, face_id=face_id, bad_rows=bad_rows,
    )  # fmt: skip
    gate = 0.5 if opts.min_confidence is None else opts.min_confidence
    report = InputReport(str(path), reader="py-feat CSV")
    tol = Tolerance(report, opts.bad_rows)
    table = CsvTable(path, report=report, tolerance=tol)
    au_cols = _au_columns(table, _PYFEAT_AU, default_au_names("human"))
    has_box = all(c in table.columns for c in _BOX)
    # one group per frame: (frame value, [(line, cells, box)])
    groups: list[tuple[float, list[tuple[int, list[str], FaceBox | None]]]] = []
    total = 0
    for index, (line, cells) in enumerate(table.rows()):
        total += 1
        try:
            frame = table.number(cells, line, "frame") if "frame" in table.columns else float(index)
            box = FaceBox(*(table.value(cells, line, c) for c in _BOX)) if has_box else None
            if box is not None and any(math.isnan(v) for v in (box.x, box.y, box.w, box.h)):
                box = None
        except BadRow as err:
            tol.handle(err)
            continue
        if groups and groups[-1][0] == frame:
            groups[-1][1].append((line, cells, box))
        else:
            groups.append((frame, [(line, cells, box)]))
    follower = FaceFollower(opts.face_id)
    rows: list[RawRow] = []
    last: dict[str, float] = {}
    for frame, members in groups:
        pick = follower.pick([b for _, _, b in members])
        if len(members) > 1:
            report.skip("rows of other faces in the same frame", len(members) - (pick is not None))
        if pick is None:
            rows.append(RawRow(members[0][0], frame, None))
            continue
        line, cells, _ = members[pick]
        try:
            score = table.value(cells, line, "FaceScore") if "FaceScore" in table.columns else 1.0
            values: dict[str, float] = {}
            for column, name in au_cols.items():
                raw = table.value(cells, line, column)
                where = table.where(line, column)
                values[name] = raw if math.isnan(raw) else tol.ranged(raw, 0.0, 1.0, where=where, what="py-feat's")
        except BadRow as err:
            tol.handle(err)
            continue
        if not math.isnan(score) and score < gate:
            rows.append(RawRow(line, frame, None))
            continue
        rows.append(RawRow(line, frame, fill_cells(values, last, report)))
    report.faces = follower.describe()
    time_col = "frame" if "frame" in table.columns else None
    if time_col is None and opts.time_unit == "auto":
        opts = _options(opts, time_unit="frames")
    recording = assemble(
        rows, report, opts, tol, kind="aus", time_column=time_col or "row", default_fps=30.0, total_rows=total
    )
    if len(rows) == 1:
        report.notes.append("one row: a still image (play holds it: --hold)")
    return recording
