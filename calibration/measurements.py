"""Measured calibration points from a CSV file: one ``role,target,tick`` row per measurement.

A header row ``role,target,tick`` is optional; blank lines and lines starting with ``#`` are skipped.
Every error names the file and the 1-based line, so a typo is found where it was typed.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from calibration.errors import MeasurementCsvError
from calibration.servo import MAX_POSITION_TICK, MIN_POSITION_TICK

HEADER = ("role", "target", "tick")


@dataclass(frozen=True)
class Measurement:
    """One measured point: the servo at ``tick`` puts its actuator at ``target`` (deg or mm)."""

    role: str
    target: float
    tick: int
    line: int = 0  # 1-based line in the source file, 0 when captured live


def read_measurements_csv(
    path: str | os.PathLike[str], roles: Collection[str] | None = None
) -> dict[str, list[Measurement]]:
    """Role -> measurements in file order. ``roles`` (if given) are the only roles accepted.

    Checks per row: 3 columns, a known role, a finite target, an integer tick in 0..4095; per role:
    no repeated target, ticks strictly monotone in the target (the error names both lines).
    """
    p = Path(path)
    name = str(p)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as err:
        raise MeasurementCsvError(name, 0, f"cannot read the measurement file ({err.strerror})") from err
    out: dict[str, list[Measurement]] = {}
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row]
        if not cells or all(not c for c in cells) or cells[0].startswith("#"):
            continue
        if tuple(c.lower() for c in cells) == HEADER:
            continue
        if len(cells) != 3:
            raise MeasurementCsvError(
                name, lineno, f"expected 3 columns role,target,tick, got {len(cells)}: {row}"
            )
        role, target_s, tick_s = cells
        if not role:
            raise MeasurementCsvError(name, lineno, "empty role")
        if roles is not None and role not in roles:
            raise MeasurementCsvError(name, lineno, f"unknown role '{role}'; expected one of {sorted(roles)}")
        try:
            target = float(target_s)
        except ValueError:
            raise MeasurementCsvError(name, lineno, f"target {target_s!r} is not a number") from None
        if not math.isfinite(target):
            raise MeasurementCsvError(name, lineno, f"target {target_s!r} is not a finite number")
        try:
            tick = int(tick_s)
        except ValueError:
            raise MeasurementCsvError(name, lineno, f"tick {tick_s!r} is not an integer") from None
        if not MIN_POSITION_TICK <= tick <= MAX_POSITION_TICK:
            raise MeasurementCsvError(
                name, lineno, f"tick {tick} is outside {MIN_POSITION_TICK}..{MAX_POSITION_TICK}"
            )
        out.setdefault(role, []).append(Measurement(role, target, tick, lineno))
    if not out:
        raise MeasurementCsvError(name, 0, "no measurements found; expected rows role,target,tick")
    for role, rows in out.items():
        check_monotone_rows(name, role, rows)
    return out


def check_monotone_rows(file: str, role: str, rows: list[Measurement]) -> None:
    """Raise MeasurementCsvError unless ticks are strictly monotone in the target (naming the lines)."""
    ordered = sorted(rows, key=lambda m: m.target)
    for a, b in zip(ordered, ordered[1:], strict=False):
        if a.target == b.target:
            raise MeasurementCsvError(
                file, b.line, f"role '{role}': target {b.target:g} already measured on line {a.line}"
            )
    if len(ordered) < 2:
        raise MeasurementCsvError(
            file, ordered[0].line, f"role '{role}': only one measurement; expected at least 2 (both ends)"
        )
    sign = 1 if ordered[1].tick > ordered[0].tick else -1
    for a, b in zip(ordered, ordered[1:], strict=False):
        step = (b.tick - a.tick) * sign
        if step <= 0:
            order = "increasing" if sign > 0 else "decreasing"
            raise MeasurementCsvError(
                file,
                b.line,
                f"role '{role}': ticks are not strictly {order} in the target: line {a.line} "
                f"({a.target:g} -> {a.tick}) and line {b.line} ({b.target:g} -> {b.tick})",
            )
