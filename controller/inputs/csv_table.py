"""CSV plumbing for tracker files: columns by header name (stripped of spaces), cells parsed with errors
that name the file, line and column."""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator
from pathlib import Path

from servoface.controller.inputs.errors import InputError


class CsvTable:
    """A CSV file read as (line number, row) with a normalised header (``" AU01_r"`` -> ``"AU01_r"``)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self._text = self.path.read_text(encoding="utf-8-sig")
        except (OSError, UnicodeDecodeError) as err:
            raise InputError(f"{self.path}: cannot read: {err}") from err
        lines = self._text.splitlines()
        if not lines or not lines[0].strip():
            raise InputError(f"{self.path}: empty file, expected a header line")
        self.header = [h.strip() for h in next(csv.reader([lines[0]]))]
        seen: set[str] = set()
        for i, name in enumerate(self.header, start=1):
            if not name:
                raise InputError(f"{self.path}: line 1, column {i}: empty column name")
            if name in seen:
                raise InputError(f"{self.path}: line 1, column {i}: column {name!r} appears twice")
            seen.add(name)
        self.columns = {name: i for i, name in enumerate(self.header)}

    def require(self, *names: str) -> None:
        missing = [n for n in names if n not in self.columns]
        if missing:
            raise InputError(
                f"{self.path}: missing required column(s) {missing}; header has "
                f"{', '.join(self.header[:10])}{', ...' if len(self.header) > 10 else ''}"
            )

    def rows(self) -> Iterator[tuple[int, list[str]]]:
        """(1-based line number, cells) for each non-blank data line; a short/long row is an error."""
        reader = csv.reader(self._text.splitlines()[1:])
        for offset, cells in enumerate(reader):
            line = offset + 2
            if not cells or all(not c.strip() for c in cells):
                continue
            if len(cells) != len(self.header):
                raise InputError(
                    f"{self.path}: line {line}: {len(cells)} cells, expected {len(self.header)} (one per header column)"
                )
            yield line, cells

    def cell(self, cells: list[str], line: int, column: str) -> str:
        return cells[self.columns[column]].strip()

    def number(self, cells: list[str], line: int, column: str, *, allow_empty: bool = False) -> float:
        """A finite float cell; NaN / inf / text raise InputError naming file, line and column."""
        text = self.cell(cells, line, column)
        where = f"{self.path}: line {line}, column {column!r} (#{self.columns[column] + 1})"
        if not text or text.lower() == "nan":
            if allow_empty:
                return math.nan
            raise InputError(f"{where}: empty or NaN, expected a finite number")
        try:
            value = float(text)
        except ValueError as err:
            raise InputError(f"{where}: {text!r} is not a number") from err
        if not math.isfinite(value):
            raise InputError(f"{where}: {text!r} is not finite, expected a finite number")
        return value

    def where(self, line: int, column: str) -> str:
        return f"{self.path}: line {line}, column {column!r}"
