"""Calibration files: JSON with ``schema_version``, read strictly and written atomically.

Layout (schema 1)::

    {
      "schema_version": 1,
      "head": "human",
      "units": {"ticks_per_turn": 4096, "tick": "...", "deg": "...", "mm": "..."},
      "metadata": {"created_utc": "2026-11-24T12:00:00Z", "method": "builtin|procedure|csv",
                   "source": "...", "notes": "..."},
      "servos": [
        {"role": "jaw", "id": 18, "model": "XL330-M288", "unit": "deg",
         "curve": {"kind": "linear", "offset_tick": 2048, "scale_tick_per_unit": 11.378, "direction": 1},
                  | {"kind": "piecewise_linear" | "pchip", "points": [[target, tick], ...]},
         "limits": {"min_tick": 2048, "max_tick": 2333, "min_target": 0.0, "max_target": 25.0},
         "neutral_tick": 2048,
         "measured_points": [[target, tick], ...],
         "coupling": {"kind": "rbf_multiquadric", "neighbours": ["role", ...],
                      "inputs": [[own_tick, neighbour_tick, ...], ...], "outputs": [mm, ...],
                      "smoothing": 0.0}            (optional)
        }, ...
      ]
    }

Every error is a :class:`CalibrationFileError` naming the file, the JSON path (``servos[3].curve.points``)
and what was expected. Unknown keys are errors too (a typo must not silently drop a limit).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from servoface.calibration.boundedfile import read_bounded
from servoface.calibration.curves import (
    TICKS_PER_TURN,
    Curve,
    LinearCurve,
    PchipCurve,
    PiecewiseLinearCurve,
    points_list,
)
from servoface.calibration.errors import CalibrationError, CalibrationFileError
from servoface.calibration.head import CalibrationMetadata, HeadCalibration
from servoface.calibration.rbf import RbfMap
from servoface.calibration.servo import UNITS, RbfCoupling, ServoCalibration

SCHEMA_VERSION = 1
METHODS = ("procedure", "csv", "builtin")
UNITS_DOC: dict[str, Any] = {
    "ticks_per_turn": TICKS_PER_TURN,
    "tick": "Dynamixel Goal/Present Position pulse, 4096 per turn, 2048 = centre",
    "deg": "joint angle, degrees, right-hand rule about the joint axis",
    "mm": "skin-anchor pull, millimetres along its line of action",
}

_TOP_KEYS = {"schema_version", "head", "units", "metadata", "servos"}
_SERVO_KEYS = {
    "role",
    "id",
    "model",
    "unit",
    "curve",
    "limits",
    "neutral_tick",
    "measured_points",
    "coupling",
}
_LIMIT_KEYS = {"min_tick", "max_tick", "min_target", "max_target"}


def shown(value: Any, limit: int = 60) -> str:
    """A short repr for messages (never raises: deep nesting, huge integers, lone surrogates)."""
    try:
        text = repr(value)
    except (RecursionError, ValueError):
        text = f"<{type(value).__name__} nested too deeply>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


class _Reader:
    """Typed access into parsed JSON that reports the file and JSON path on every failure."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, path: str, message: str) -> CalibrationFileError:
        return CalibrationFileError(self.file, path, message)

    def obj(self, value: Any, path: str, keys: set[str], required: set[str]) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(path, f"expected an object, got {type(value).__name__}")
        missing = sorted(required - value.keys())
        if missing:
            raise self.fail(path, f"missing key(s) {missing}; expected {sorted(required)}")
        unknown = sorted(value.keys() - keys)
        if unknown:
            raise self.fail(path, f"unexpected key(s) {unknown}; allowed {sorted(keys)}")
        return value

    def integer(self, value: Any, path: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(path, f"expected an integer, got {shown(value)} ({type(value).__name__})")
        if not -(2**31) <= value < 2**31:
            raise self.fail(path, f"expected an integer that fits 32 bits, got {shown(value)}")
        return value

    def number(self, value: Any, path: str) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(path, f"expected a number, got {shown(value)} ({type(value).__name__})")
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number):
            raise self.fail(path, f"expected a finite number, got {shown(value)}")
        return number

    def string(self, value: Any, path: str, choices: tuple[str, ...] = ()) -> str:
        if not isinstance(value, str) or not value:
            raise self.fail(path, f"expected a non-empty string, got {shown(value)}")
        if choices and value not in choices:
            raise self.fail(path, f"expected one of {list(choices)}, got {shown(value)}")
        return value

    def rows(self, value: Any, path: str, width: int | None) -> list[list[float]]:
        if not isinstance(value, list):
            raise self.fail(path, f"expected a list of [target, tick] pairs, got {type(value).__name__}")
        out = []
        for i, row in enumerate(value):
            if not isinstance(row, list) or (width is not None and len(row) != width):
                raise self.fail(f"{path}[{i}]", f"expected a list of {width} numbers, got {shown(row)}")
            out.append([self.number(v, f"{path}[{i}][{j}]") for j, v in enumerate(row)])
        return out


def _curve(r: _Reader, value: Any, path: str) -> Curve:
    if not isinstance(value, dict):
        raise r.fail(path, f"expected an object, got {type(value).__name__}")
    kind = r.string(value.get("kind"), f"{path}.kind", ("linear", "piecewise_linear", "pchip"))
    try:
        if kind == "linear":
            v = r.obj(
                value,
                path,
                {"kind", "offset_tick", "scale_tick_per_unit", "direction"},
                {"kind", "offset_tick", "scale_tick_per_unit", "direction"},
            )
            direction = r.integer(v["direction"], f"{path}.direction")
            if direction not in (1, -1):
                raise r.fail(f"{path}.direction", f"expected 1 or -1, got {direction}")
            scale = r.number(v["scale_tick_per_unit"], f"{path}.scale_tick_per_unit")
            if scale <= 0:
                raise r.fail(f"{path}.scale_tick_per_unit", f"expected > 0, got {scale}")
            return LinearCurve(r.number(v["offset_tick"], f"{path}.offset_tick"), scale, direction)
        v = r.obj(value, path, {"kind", "points"}, {"kind", "points"})
        pts = r.rows(v["points"], f"{path}.points", 2)
        cls = PiecewiseLinearCurve if kind == "piecewise_linear" else PchipCurve
        try:
            return cls(pts)
        except CalibrationError as err:
            raise r.fail(f"{path}.points", str(err)) from err
    except CalibrationFileError:
        raise
    except CalibrationError as err:
        raise r.fail(path, str(err)) from err


def _coupling(r: _Reader, value: Any, path: str) -> RbfCoupling:
    keys = {"kind", "neighbours", "inputs", "outputs", "smoothing"}
    v = r.obj(value, path, keys, keys)
    r.string(v["kind"], f"{path}.kind", ("rbf_multiquadric",))
    if not isinstance(v["neighbours"], list) or not v["neighbours"]:
        raise r.fail(f"{path}.neighbours", "expected a non-empty list of roles")
    neighbours = tuple(r.string(n, f"{path}.neighbours[{i}]") for i, n in enumerate(v["neighbours"]))
    inputs = r.rows(v["inputs"], f"{path}.inputs", 1 + len(neighbours))
    if not isinstance(v["outputs"], list):
        raise r.fail(f"{path}.outputs", "expected a list of numbers")
    outputs = [r.number(o, f"{path}.outputs[{i}]") for i, o in enumerate(v["outputs"])]
    if len(outputs) != len(inputs):
        raise r.fail(f"{path}.outputs", f"expected {len(inputs)} values (one per input row), got {len(outputs)}")
    smoothing = r.number(v["smoothing"], f"{path}.smoothing")
    try:
        return RbfCoupling(neighbours, RbfMap.fit(inputs, outputs, smoothing=smoothing))
    except CalibrationError as err:
        raise r.fail(path, str(err)) from err


def _servo(r: _Reader, value: Any, path: str) -> ServoCalibration:
    v = r.obj(value, path, _SERVO_KEYS, _SERVO_KEYS - {"coupling", "measured_points"})
    role = r.string(v["role"], f"{path}.role")
    servo_id = r.integer(v["id"], f"{path}.id")
    if not 0 <= servo_id <= 252:
        raise r.fail(f"{path}.id", f"expected a servo id 0..252, got {servo_id}")
    model = r.string(v["model"], f"{path}.model")
    unit = r.string(v["unit"], f"{path}.unit", UNITS)
    curve = _curve(r, v["curve"], f"{path}.curve")
    lim = r.obj(v["limits"], f"{path}.limits", _LIMIT_KEYS, {"min_tick", "max_tick"})
    min_tick = r.integer(lim["min_tick"], f"{path}.limits.min_tick")
    max_tick = r.integer(lim["max_tick"], f"{path}.limits.max_tick")
    lo = r.number(lim["min_target"], f"{path}.limits.min_target") if "min_target" in lim else float("nan")
    hi = r.number(lim["max_target"], f"{path}.limits.max_target") if "max_target" in lim else float("nan")
    neutral = r.integer(v["neutral_tick"], f"{path}.neutral_tick")
    measured = r.rows(v.get("measured_points", []), f"{path}.measured_points", 2)
    coupling = _coupling(r, v["coupling"], f"{path}.coupling") if "coupling" in v else None
    try:
        return ServoCalibration(
            role,
            servo_id,
            model,
            curve,
            min_tick,
            max_tick,
            neutral,
            unit,  # type: ignore[arg-type]
            min_target=lo,
            max_target=hi,
            measured_points=np.asarray(measured, dtype=np.float64).reshape(-1, 2),
            coupling=coupling,
        )
    except CalibrationError as err:
        raise r.fail(path, str(err)) from err


def calibration_from_dict(data: Any, file: str = "<dict>") -> HeadCalibration:
    """Validate parsed JSON into a :class:`HeadCalibration` (errors name ``file`` and the JSON path)."""
    r = _Reader(file)
    top = r.obj(data, "", _TOP_KEYS, _TOP_KEYS - {"metadata"})
    version = top["schema_version"]
    if isinstance(version, bool) or not isinstance(version, int) or version != SCHEMA_VERSION:
        raise r.fail(
            "schema_version", f"unknown schema version {shown(version)}; this servoface reads {SCHEMA_VERSION}"
        )
    head = r.string(top["head"], "head")
    units = top["units"]
    if not isinstance(units, dict) or units.get("ticks_per_turn") != TICKS_PER_TURN:
        got = units.get("ticks_per_turn") if isinstance(units, dict) else units
        raise r.fail("units.ticks_per_turn", f"expected {TICKS_PER_TURN}, got {shown(got)}")
    meta = _metadata(r, top.get("metadata", {}))
    servos_raw = top["servos"]
    if not isinstance(servos_raw, list) or not servos_raw:
        raise r.fail("servos", "expected a non-empty list of servo entries")
    servos: list[ServoCalibration] = []
    seen_role: dict[str, int] = {}
    seen_id: dict[int, int] = {}
    for i, raw in enumerate(servos_raw):
        s = _servo(r, raw, f"servos[{i}]")
        if s.role in seen_role:
            raise r.fail(f"servos[{i}].role", f"role '{s.role}' already used by servos[{seen_role[s.role]}]")
        if s.servo_id in seen_id:
            j = seen_id[s.servo_id]
            raise r.fail(f"servos[{i}].id", f"id {s.servo_id} already used by servos[{j}] ('{servos[j].role}')")
        seen_role[s.role] = i
        seen_id[s.servo_id] = i
        servos.append(s)
    try:
        return HeadCalibration(head, servos, meta)
    except CalibrationError as err:
        raise r.fail("servos", str(err)) from err


def _metadata(r: _Reader, value: Any) -> CalibrationMetadata:
    if not isinstance(value, dict):
        raise r.fail("metadata", f"expected an object, got {type(value).__name__}")
    fields = {}
    for key in ("created_utc", "method", "source", "notes"):
        if key in value and not isinstance(value[key], str):
            raise r.fail(f"metadata.{key}", f"expected a string, got {shown(value[key])}")
        fields[key] = value.get(key, "")
    if fields["method"] and fields["method"] not in METHODS:
        raise r.fail("metadata.method", f"expected one of {list(METHODS)}, got {shown(fields['method'])}")
    extra = {k: v for k, v in value.items() if k not in fields}
    return CalibrationMetadata(
        fields["created_utc"], fields["method"] or "builtin", fields["source"], fields["notes"], extra
    )


def calibration_to_dict(cal: HeadCalibration) -> dict[str, Any]:
    """The JSON-ready form of a calibration (round-trips through :func:`calibration_from_dict`)."""
    servos = []
    for s in cal.servos:
        entry: dict[str, Any] = {
            "role": s.role,
            "id": s.servo_id,
            "model": s.model,
            "unit": s.unit,
            "curve": s.curve.to_dict(),
            "limits": {
                "min_tick": int(s.min_tick),
                "max_tick": int(s.max_tick),
                "min_target": s.min_target,
                "max_target": s.max_target,
            },
            "neutral_tick": int(s.neutral_tick),
            "measured_points": points_list(s.measured_points),
        }
        if s.coupling is not None:
            entry["coupling"] = {"neighbours": list(s.coupling.neighbours), **s.coupling.map.to_dict()}
        servos.append(entry)
    m = cal.metadata
    meta: dict[str, Any] = {
        "created_utc": m.created_utc,
        "method": m.method,
        "source": m.source,
        "notes": m.notes,
        **dict(m.extra),
    }
    return {
        "schema_version": SCHEMA_VERSION,
        "head": cal.head,
        "units": dict(UNITS_DOC),
        "metadata": meta,
        "servos": servos,
    }


def load_calibration(path: str | os.PathLike[str]) -> HeadCalibration:
    """Read and validate a calibration file (a regular file of at most 16 MiB, see :mod:`.boundedfile`)."""
    p = Path(path)
    try:
        raw = read_bounded(p, lambda reason: CalibrationFileError(str(p), "", reason), what="a calibration file")
        text = raw.decode("utf-8")
    except OSError as err:
        raise CalibrationFileError(str(p), "", f"cannot read the calibration file ({err.strerror})") from err
    except UnicodeDecodeError as err:
        byte = f"byte 0x{err.object[err.start]:02x} at offset {err.start}"
        raise CalibrationFileError(str(p), "", f"not a calibration JSON file (not UTF-8 text: {byte})") from err
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise CalibrationFileError(
            str(p), "", f"not valid JSON at line {err.lineno} column {err.colno}: {err.msg}"
        ) from err
    except RecursionError as err:
        raise CalibrationFileError(str(p), "", "nested too deeply to be a calibration file") from err
    return calibration_from_dict(data, str(p))


def save_calibration(cal: HeadCalibration, path: str | os.PathLike[str]) -> Path:
    """Write atomically (temp file in the same folder, fsync, rename); returns the path."""
    p = Path(path)
    return write_atomic(p, dumps(calibration_to_dict(cal)) + "\n")


def dumps(value: Any, indent: int = 0) -> str:
    """JSON with 2-space indents, but flat lists (points, input rows) kept on one line."""
    pad, inner = " " * indent, " " * (indent + 2)
    if isinstance(value, dict) and value:
        items = [f"{inner}{json.dumps(k)}: {dumps(v, indent + 2)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(value, list) and value and any(isinstance(v, dict | list) for v in value):
        if all(isinstance(v, list) and not any(isinstance(x, dict | list) for x in v) for v in value):
            rows = [f"{inner}{json.dumps(v, allow_nan=False)}" for v in value]
        else:
            rows = [f"{inner}{dumps(v, indent + 2)}" for v in value]
        return "[\n" + ",\n".join(rows) + "\n" + pad + "]"
    return json.dumps(value, allow_nan=False)


def write_atomic(path: Path, text: str) -> Path:
    """Replace ``path`` with ``text`` so a reader sees the old file or the new one, never half of it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def metadata_now(method: str, source: str = "", notes: str = "", **extra: Any) -> CalibrationMetadata:
    """Metadata stamped with the current UTC time."""
    from datetime import UTC, datetime

    if method not in METHODS:
        raise CalibrationError(f"metadata method {method!r}: expected one of {list(METHODS)}")
    stamp = datetime.now(UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    return CalibrationMetadata(stamp, method, source, notes, dict(extra))
