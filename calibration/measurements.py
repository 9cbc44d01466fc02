"""Measured calibration points from a CSV file: one ``role,target,tick`` row per measurement.

A header row ``role,target,tick`` is optional; blank lines and lines starting with ``#`` are skipped.
A coupled skin anchor (its pull also depends on neighbour servos) adds one ``neighbour_role=tick`` cell per
neighbour, e.g. ``lip_corner_l,4.2,2310,lip_depressor_l=2100``; every row of that role must name the same
neighbours. Every error names the file and the 1-based line, so a typo is found where it was typed.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from servoface.calibration.boundedfile import read_bounded
from servoface.calibration.errors import MeasurementCsvError
from servoface.calibration.servo import MAX_POSITION_TICK, MIN_POSITION_TICK

HEADER = ("role", "target", "tick")


@dataclass(frozen=True)
class Measurement:
    """One measured point: the servo at ``tick`` puts its actuator at ``target`` (deg or mm).

    ``neighbours``: (role, tick) of the other servos the target depends on (coupled anchors only).
    """

    role: str
    target: float
    tick: int
    line: int = 0  # 1-based line in the source file, 0 when captured live
    neighbours: tuple[tuple[str, int], ...] = ()


def _tick(name: str, lineno: int, text: str, what: str) -> int:
    try:
        tick = int(text)
    except ValueError:
        raise MeasurementCsvError(name, lineno, f"{what} {text!r} is not an integer") from None
    if not MIN_POSITION_TICK <= tick <= MAX_POSITION_TICK:
        raise MeasurementCsvError(name, lineno, f"{what} {tick} is outside {MIN_POSITION_TICK}..{MAX_POSITION_TICK}")
    return tick


def _row(
    name: str, lineno: int, cells: list[str], roles: Collection[str] | None, others: Collection[str] | None
) -> Measurement:
    if len(cells) < 3:
        raise MeasurementCsvError(
            name,
            lineno,
            f"expected 3 columns role,target,tick (+ neighbour=tick cells), got {len(cells)}: {cells}",
        )
    role, target_s, tick_s = cells[:3]
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
    tick = _tick(name, lineno, tick_s, "tick")
    neighbours: list[tuple[str, int]] = []
    for cell in cells[3:]:
        other, sep, value = cell.partition("=")
        other = other.strip()
        if not sep or not other:
            raise MeasurementCsvError(name, lineno, f"extra cell {cell!r}: expected neighbour_role=tick")
        if other == role or (others is not None and other not in others):
            raise MeasurementCsvError(name, lineno, f"neighbour '{other}' of '{role}' is not another known role")
        if other in dict(neighbours):
            raise MeasurementCsvError(name, lineno, f"neighbour '{other}' given twice")
        neighbours.append((other, _tick(name, lineno, value.strip(), f"tick of neighbour '{other}'")))
    return Measurement(role, target, tick, lineno, tuple(neighbours))


def _decode(name: str, raw: bytes) -> str:
    """UTF-8 text, with or without the byte-order mark a spreadsheet's "CSV UTF-8" export puts first; any other
    encoding is refused naming the line and the byte (a spreadsheet's legacy "CSV" export, e.g. Latin-1)."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        bom = len(raw) >= 3 and raw[:3] == b"\xef\xbb\xbf"
        start = err.start + (3 if bom else 0)
        line = raw[:start].count(b"\n") + 1
        raise MeasurementCsvError(
            name, line, f"not UTF-8 text (byte 0x{raw[start]:02x}); expected a CSV saved as UTF-8"
        ) from err


def read_measurements_csv(
    path: str | os.PathLike[str],
    roles: Collection[str] | None = None,
    neighbour_roles: Collection[str] | None = None,
    skip_roles: Collection[str] = (),
) -> dict[str, list[Measurement]]:
    """Role -> measurements in file order. ``roles`` (if given) are the only roles accepted in the first
    column, ``neighbour_roles`` (default: ``roles``) the only ones in neighbour cells. Rows of ``skip_roles``
    (servos of the head not calibrated this time, e.g. outside ``--roles``) are passed over unread.

    Checks per row: a known role, a finite target, an integer tick in 0..4095, well-formed neighbour cells;
    per role: the same neighbours on every row; for each setting of the neighbours, no repeated target and
    ticks strictly monotone in the target (the error names both lines).
    """
    p = Path(path)
    name = str(p)
    try:
        raw = read_bounded(p, lambda reason: MeasurementCsvError(name, 0, reason), what="a measurement CSV")
    except OSError as err:
        raise MeasurementCsvError(name, 0, f"cannot read the measurement file ({err.strerror})") from err
    text = _decode(name, raw)
    out: dict[str, list[Measurement]] = {}
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row]
        if not cells or all(not c for c in cells) or cells[0].startswith("#"):
            continue
        if tuple(c.lower() for c in cells) == HEADER or cells[0] in skip_roles:
            continue
        m = _row(name, lineno, cells, roles, roles if neighbour_roles is None else neighbour_roles)
        rows = out.setdefault(m.role, [])
        if rows and [n for n, _ in rows[0].neighbours] != [n for n, _ in m.neighbours]:
            raise MeasurementCsvError(
                name,
                lineno,
                f"role '{m.role}': neighbours {[n for n, _ in m.neighbours]} differ from line "
                f"{rows[0].line} ({[n for n, _ in rows[0].neighbours]}); expected the same on every row",
            )
        rows.append(m)
    if not out:
        raise MeasurementCsvError(name, 0, "no measurements found; expected rows role,target,tick")
    for role, rows in out.items():
        groups: dict[tuple[tuple[str, int], ...], list[Measurement]] = {}
        for m in rows:
            groups.setdefault(m.neighbours, []).append(m)
        if not rows[0].neighbours and len(rows) < 2:
            raise MeasurementCsvError(
                name, rows[0].line, f"role '{role}': only one measurement; expected at least 2 (both ends)"
            )
        for group in groups.values():
            check_monotone_rows(name, role, group)
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
        return
    sign = 1 if ordered[1].tick > ordered[0].tick else -1
    for a, b in zip(ordered, ordered[1:], strict=False):
        if (b.tick - a.tick) * sign <= 0:
            order = "increasing" if sign > 0 else "decreasing"
            raise MeasurementCsvError(
                file,
                b.line,
                f"role '{role}': ticks are not strictly {order} in the target: line {a.line} "
                f"({a.target:g} -> {a.tick}) and line {b.line} ({b.target:g} -> {b.tick})",
            )
