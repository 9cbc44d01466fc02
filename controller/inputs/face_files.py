"""Recorded blendshape / AU files -> a Recording: JSON lines (one message per line, messages.py) and
blendshape CSVs (ARKit / MediaPipe names as columns; Live Link Face's CSV export included).

JSON lines: every line is a message object with a time ``t`` (s); blank lines and lines starting with
``#`` are skipped. Errors name the file, the line and the field (``aus.AU12``).

Blendshape CSV: one column per blendshape (exact ARKit spelling or Live Link Face's capitalised one), a
time column ``t`` / ``t_s`` / ``timestamp`` (s), or ``frame`` / ``Timecode`` (HH:MM:SS:FF[.sub]) with
``fps``; optional ``yaw_deg, pitch_deg, roll_deg`` (head_pose.py convention) and ``confidence``. Live Link
Face's ``BlendShapeCount`` and its head/eye rotation columns (units not documented) are ignored with a
note; any other unknown column is an error.

:func:`load_recording` picks the reader from the file: ``.jsonl``/``.ndjson``, ``.fap``, or a ``.csv`` by
its header (OpenFace ``AUxx_r`` columns, py-feat ``AUxx`` columns, else blendshapes).
"""

from __future__ import annotations

import math
from pathlib import Path

from servoface.controller.frame import check_face_type
from servoface.controller.inputs.csv_table import CsvTable
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.head_pose import head_pose_aus
from servoface.controller.inputs.messages import MessageDecoder
from servoface.controller.inputs.recorded import InputReport, Recording, frames_with_policy
from servoface.controller.inputs.sides import mirror_aus
from servoface.sim.rig import FaceType

_TIME_COLUMNS = ("t", "t_s", "timestamp")
_POSE_COLUMNS = ("yaw_deg", "pitch_deg", "roll_deg")
_LLF_IGNORED = frozenset({
    "BlendShapeCount", "HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll",
    "RightEyeYaw", "RightEyePitch", "RightEyeRoll",
})  # fmt: skip


def read_jsonl(
    path: str | Path,
    face_type: FaceType = "human",
    *,
    mirror: bool = False,
    min_confidence: float = 0.0,
    lost: str = "hold",
    decay_s: float = 0.5,
    interpolate: bool = True,
) -> Recording:
    """Read a JSON-lines file of messages (each with ``t``) into a Recording."""
    file = Path(path)
    try:
        lines = file.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{file}: cannot read: {err}") from err
    decoder = MessageDecoder(check_face_type(face_type), mirror=mirror)
    rows: list[tuple[float, dict[str, float] | None]] = []
    report = InputReport(str(file))
    last_t = -math.inf
    for number, line in enumerate(lines, start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        msg = decoder.decode_line(line, where=f"{file}: line {number}")
        if msg.t_s is None:
            raise InputError(f"{file}: line {number}.t: missing; every line of a recording needs a time t (s)")
        if msg.t_s < last_t:
            raise InputError(f"{file}: line {number}.t: {msg.t_s:g} s is earlier than the line before")
        last_t = msg.t_s
        report.rows += 1
        rows.append((msg.t_s, msg.aus if msg.confidence >= min_confidence else None))
    if not rows:
        raise InputError(f"{file}: no messages")
    frames, report.held = frames_with_policy(rows, face_type, lost=lost, decay_s=decay_s)
    return Recording(frames, face_type, interpolate=interpolate, source=str(file), report=report)


def _timecode_s(text: str, fps: float, where: str) -> float:
    parts = text.replace(";", ":").split(":")
    try:
        h, m, s, f = (float(p) for p in parts)
    except ValueError as err:
        raise InputError(f"{where}: {text!r} is not a timecode HH:MM:SS:FF[.sub]") from err
    return h * 3600 + m * 60 + s + f / fps


def read_blendshape_csv(
    path: str | Path,
    *,
    fps: float = 60.0,
    mirror: bool = False,
    min_confidence: float = 0.0,
    lost: str = "hold",
    decay_s: float = 0.5,
    interpolate: bool = True,
) -> Recording:
    """Read a blendshape CSV into a human Recording (see the module doc for the columns)."""
    if not (isinstance(fps, int | float) and 0 < fps <= 10_000):
        raise InputError(f"fps: expected a frame rate 0 < fps <= 10000, got {fps!r}")
    table = CsvTable(path)
    decoder = MessageDecoder("human")
    bmap = decoder.blendshape_map
    time_col = next((c for c in _TIME_COLUMNS if c in table.columns), None)
    if time_col is None:
        time_col = next((c for c in ("frame", "Timecode") if c in table.columns), None)
    if time_col is None:
        raise InputError(
            f"{table.path}: missing a time column; expected one of {list(_TIME_COLUMNS) + ['frame', 'Timecode']}"
        )
    shape_cols: dict[str, str] = {}
    report = InputReport(str(table.path))
    ignored = []
    for column in table.header:
        if column in (time_col, "confidence", *_POSE_COLUMNS, *_TIME_COLUMNS, "frame", "Timecode"):
            continue
        if column in _LLF_IGNORED:
            ignored.append(column)
            continue
        shape_cols[column] = bmap.resolve(column, field=f"{table.path}: line 1, column {column!r}")
    if not shape_cols:
        raise InputError(f"{table.path}: no blendshape columns found (expected e.g. mouthSmileLeft)")
    if ignored:
        report.notes.append(f"ignored columns {ignored}")
    has_pose = any(c in table.columns for c in _POSE_COLUMNS)
    rows: list[tuple[float, dict[str, float] | None]] = []
    last_t = -math.inf
    for line, cells in table.rows():
        if time_col == "Timecode":
            t_s = _timecode_s(table.cell(cells, line, time_col), fps, table.where(line, time_col))
        else:
            t_s = table.number(cells, line, time_col) / (fps if time_col == "frame" else 1.0)
        if t_s < last_t:
            raise InputError(f"{table.where(line, time_col)}: time goes backwards ({t_s:g} s)")
        last_t = t_s
        shapes = {name: table.number(cells, line, col) for col, name in shape_cols.items()}
        aus = bmap.to_aus(shapes, where=f"{table.path}: line {line}")
        if has_pose:
            ypr = [table.number(cells, line, c) if c in table.columns else 0.0 for c in _POSE_COLUMNS]
            for c, v in zip(_POSE_COLUMNS, ypr, strict=True):
                if abs(v) > 180:
                    raise InputError(f"{table.where(line, c)}: {v:g} deg is outside ±180")
            aus.update(head_pose_aus(ypr[0], ypr[1], ypr[2]))
        confidence = table.number(cells, line, "confidence") if "confidence" in table.columns else 1.0
        report.rows += 1
        good = confidence >= min_confidence
        rows.append((t_s, (mirror_aus(aus, "human") if mirror else aus) if good else None))
    if not rows:
        raise InputError(f"{table.path}: no data rows")
    frames, report.held = frames_with_policy(rows, "human", lost=lost, decay_s=decay_s)
    return Recording(frames, "human", interpolate=interpolate, source=str(table.path), report=report)


def load_recording(
    path: str | Path, face_type: FaceType = "human", *, mirror: bool = False, fps: float | None = None
) -> Recording:
    """Read any supported recorded file, choosing the reader by extension and CSV header. A shipped sample
    is reachable by name: ``sample:openface_smile`` (see ``servoface list samples``)."""
    from servoface.controller.errors import ControllerError
    from servoface.controller.inputs.openface import read_openface_csv, read_pyfeat_csv
    from servoface.controller.shipped import resolve_sample

    try:
        file = resolve_sample(path)
    except ControllerError as err:
        raise InputError(str(err)) from err
    suffix = file.suffix.lower()
    if suffix in (".jsonl", ".ndjson", ".json"):
        return read_jsonl(file, face_type, mirror=mirror)
    if face_type != "human":
        raise InputError(f"{file}: only JSON-lines recordings with DFACS 'aus' can drive a {face_type} head")
    if suffix == ".fap":
        from servoface.controller.inputs.fap import read_fap

        return read_fap(file, mirror=mirror, fps=fps)
    if suffix != ".csv":
        raise InputError(f"{file}: unknown recording type {suffix!r}; expected .csv, .jsonl or .fap")
    header = CsvTable(file).header
    if any(h.endswith("_r") and h.startswith("AU") for h in header):
        return read_openface_csv(file, mirror=mirror)
    if any(h.startswith("AU") and h[2:].isdigit() for h in header):
        return read_pyfeat_csv(file, mirror=mirror, fps=fps or 30.0)
    return read_blendshape_csv(file, mirror=mirror, fps=fps or 60.0)
