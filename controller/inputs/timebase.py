"""Time units of a file's time column, detected from the data, printed, and overridable.

``time_unit="auto"`` (default): a column name that says its unit wins (``timestamp_ms``, ``t_us``, ``t_s``,
``frame``); otherwise the median step between rows decides: the first of seconds, milliseconds, microseconds
that makes it a frame rate a face tracker writes (``PLAUSIBLE_HZ``, 1..240 Hz). Steps no unit makes
plausible (e.g. 1 ms between rows: 1000 fps) are not trusted: rows are timed at ``fps`` instead, with a
note. ``time_unit`` ``"s"``, ``"ms"``, ``"us"`` or ``"frames"`` (time column / fps) forces a unit; a file
without a time column is timed by row at ``fps`` (the reader's default if None, reported either way).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence

from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.report import InputReport

TIME_UNITS = ("auto", "s", "ms", "us", "frames")
PLAUSIBLE_HZ = (1.0, 240.0)
_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6}


def check_fps(fps: float | None) -> float | None:
    if fps is None:
        return None
    if isinstance(fps, bool) or not isinstance(fps, int | float) or not 0 < fps <= 10_000:
        raise InputError(f"fps: expected a frame rate 0 < fps <= 10000, got {fps!r}")
    return float(fps)


def unit_from_name(column: str) -> str | None:
    low = column.lower()
    if low.endswith(("_ms", "ms")) and low not in ("ms",):
        return "ms"
    if low.endswith(("_us", "_usec")):
        return "us"
    if low.endswith("_s") or low in ("t", "time", "seconds"):
        return "s"
    if low in ("frame", "frame_idx", "frame_number"):
        return "frames"
    return None


def resolve_times(
    raw: Sequence[float],
    *,
    column: str | None,
    unit: str = "auto",
    fps: float | None = None,
    default_fps: float = 30.0,
    report: InputReport | None = None,
) -> list[float]:
    """Seconds for each row from the raw time values (``column`` None: no time column, time by row)."""
    if unit not in TIME_UNITS:
        raise InputError(f"time_unit: expected one of {TIME_UNITS}, got {unit!r}")
    rate = check_fps(fps) or default_fps
    rate_from = "given" if fps is not None else "the reader's default; set it with the fps option"
    note = ""
    if column is None:
        note = f"no time column: rows timed at {rate:g} fps ({rate_from})"
        times = [i / rate for i in range(len(raw))]
        chosen = "rows"
    else:
        chosen = unit
        how = "given"
        if unit == "auto":
            named = unit_from_name(column)
            steps = sorted(b - a for a, b in zip(raw, raw[1:], strict=False) if b > a)
            step = statistics.median(steps) if steps else None
            if named is not None:
                chosen, how = named, f"from the column name {column!r}"
            elif step is None:
                chosen, how = "s", "one row"
            else:
                chosen = next((u for u, k in _SCALE.items() if _plausible(_rate(step * k))), "rows")
                if chosen == "rows":
                    note = (
                        f"{column} steps by {step:g} between rows ({_rate(step):g}/s): no unit makes that a "
                        f"tracker's frame rate; rows timed at {rate:g} fps instead ({rate_from}; "
                        "--time-unit s|ms|us keeps the column)"
                    )
                else:
                    how = f"detected: median step {step:g} = {_rate(step * _SCALE[chosen]):.4g} fps"
        if chosen == "rows":
            times = [i / rate for i in range(len(raw))]
        elif chosen == "frames":
            times = [v / rate for v in raw]
            note = note or f"{column} in frames at {rate:g} fps ({rate_from})"
        else:
            times = [v * _SCALE[chosen] for v in raw]
            note = note or f"{column} in {chosen} ({how}; override with --time-unit)"
    if report is not None:
        report.time = note
        steps_s = [b - a for a, b in zip(times, times[1:], strict=False) if b > a]
        report.fps = round(_rate(statistics.median(steps_s)), 3) if steps_s else None
        if report.fps is not None and "fps" not in report.time:
            report.time += f"; {report.fps:g} fps"
    return times


def _rate(step: float) -> float:
    """Rows per second of a step between rows; a step too small for its reciprocal (a subnormal timestamp
    difference, or one that underflows to 0 when scaled to seconds) is an infinite rate, not a crash."""
    return 1.0 / step if step > 0 else math.inf


def _plausible(hz: float) -> bool:
    return PLAUSIBLE_HZ[0] <= hz <= PLAUSIBLE_HZ[1]
