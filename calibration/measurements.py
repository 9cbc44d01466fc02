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
MAX_ROWS_NAMED = 6  # rows a message lists in full


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


def _at(m: Measurement) -> str:
    return f"line {m.line}, target {m.target:g}"


def check_monotone_rows(file: str, role: str, rows: list[Measurement]) -> None:
    """Raise MeasurementCsvError unless ticks are strictly monotone in the target.

    The servo's direction is the one most of its steps (rows in target order) take, or on a tie the one from
    its lowest to its highest target; the error names the first step against it (both lines, targets and
    ticks), what was found there and what that direction expects.
    """
    ordered = sorted(rows, key=lambda m: m.target)
    for a, b in zip(ordered, ordered[1:], strict=False):
        if a.target == b.target:
            raise MeasurementCsvError(
                file, b.line, f"role '{role}': target {b.target:g} already measured on line {a.line}"
            )
    steps = list(zip(ordered, ordered[1:], strict=False))
    rising = sum(b.tick > a.tick for a, b in steps)
    falling = sum(b.tick < a.tick for a, b in steps)
    if rising == len(steps) or falling == len(steps):
        return
    first, last = ordered[0], ordered[-1]
    sign = (rising > falling) - (rising < falling) or (last.tick > first.tick) - (last.tick < first.tick)
    if sign == 0:  # as many steps up as down (or none either way), and both ends on one tick: no direction
        shown = MAX_ROWS_NAMED
        ticks = ", ".join(f"{m.tick} ({_at(m)})" for m in ordered[:shown])
        ticks += f" and {len(ordered) - shown} more" if len(ordered) > shown else ""
        raise MeasurementCsvError(
            file,
            last.line,
            f"role '{role}': ticks {ticks} neither rise nor fall with the target ({rising} step(s) up, {falling} "
            f"down, {len(steps) - rising - falling} flat); expected ticks strictly increasing or strictly "
            "decreasing in the target: re-measure these rows",
        )
    a, b = next((a, b) for a, b in steps if (b.tick - a.tick) * sign <= 0)
    found = (
        f"ticks stay at {a.tick} from {_at(a)} to {_at(b)}"
        if a.tick == b.tick
        else f"ticks {'fall' if b.tick < a.tick else 'rise'} from {a.tick} ({_at(a)}) to {b.tick} ({_at(b)})"
    )
    way, order = ("rise", "increasing") if sign > 0 else ("fall", "decreasing")
    raise MeasurementCsvError(
        file,
        b.line,
        f"role '{role}': {found}, but this servo's ticks {way} with the target ({max(rising, falling)} of its "
        f"{len(steps)} steps; {first.tick} at target {first.target:g} -> {last.tick} at target {last.target:g}): "
        f"expected ticks strictly {order} in the target; re-measure line {a.line} or line {b.line}",
    )
