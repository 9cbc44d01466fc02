"""Delimited text plumbing for tracker files: columns by header name (stripped of spaces), cells parsed with
errors that name the file, line and column.

What real files do and this reads: comma, tab or semicolon separators (the one the header line uses most;
with ``;`` a decimal comma ``0,5`` is read as 0.5); a UTF-8 byte-order mark; a pandas index column (an empty
or ``Unnamed: 0`` header) and a trailing separator (an empty last column name) are ignored and reported; a
last row cut short (a recording stopped mid-write) is skipped and reported. Other rows of the wrong length
are bad rows (tolerance.py decides: skip and count, or error).
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Iterator
from pathlib import Path

from servoface.calibration.boundedfile import read_bounded
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.report import InputReport
from servoface.controller.inputs.tolerance import BadRow, Tolerance, parse_number

_DELIMITERS = {",": "comma", "\t": "tab", ";": "semicolon"}
_DECIMAL_COMMA = re.compile(r"^\s*-?\d+,\d+\s*$")


MAX_FILE_BYTES = 512 * 1024 * 1024  # a tracker recording larger than this is refused, not read into memory


def read_text(path: Path, *, max_bytes: int = MAX_FILE_BYTES, what: str = "a tracker recording") -> str:
    """A text file as str (UTF-8, with or without BOM); InputError naming the file otherwise. Read through
    `read_bounded` (streams allowed: ``--input /dev/stdin``, a pipe or a terminal works; a directory or a
    device such as ``/dev/zero`` does not): at most ``max_bytes``, so a larger file is refused unread and a
    stream that runs on after ``max_bytes``, instead of taking every byte of memory."""
    try:
        data = read_bounded(
            path, lambda reason: InputError(f"{path}: {reason}"), what=what, limit_bytes=max_bytes, allow_stream=True
        )
    except OSError as err:
        raise InputError(f"{path}: cannot read: {err}") from err
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise InputError(f"{path}: not UTF-8 text (byte {err.start}): {err.reason}") from err


def sniff_delimiter(header_line: str) -> str:
    counts = {d: header_line.count(d) for d in _DELIMITERS}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] else ","


class CsvTable:
    """A delimited file read as (line number, cells) with a normalised header (``" AU01_r"`` -> ``"AU01_r"``)."""

    def __init__(
        self, path: str | Path, *, report: InputReport | None = None, tolerance: Tolerance | None = None
    ) -> None:
        self.path = Path(path)
        self.report = report
        self.tolerance = tolerance
        self._lines = read_text(self.path).splitlines()
        first = next((i for i, ln in enumerate(self._lines) if ln.strip()), None)
        if first is None:
            raise InputError(f"{self.path}: empty file, expected a header line")
        self._first = first
        self.delimiter = sniff_delimiter(self._lines[first])
        raw_header = [h.strip() for h in next(csv.reader([self._lines[first]], delimiter=self.delimiter))]
        self.ignored: list[int] = []  # column indices skipped (pandas index, trailing separator)
        seen: set[str] = set()
        for i, name in enumerate(raw_header):
            if not name or re.fullmatch(r"Unnamed: \d+", name):
                self.ignored.append(i)
                continue
            if name in seen:
                raise InputError(f"{self.path}: line {first + 1}, column {i + 1}: column {name!r} appears twice")
            seen.add(name)
        self.width = len(raw_header)
        self.header = [h for i, h in enumerate(raw_header) if i not in self.ignored]
        self.columns = {name: i for i, name in enumerate(raw_header) if i not in self.ignored}
        self.decimal_comma = False
        if self.delimiter == ";":
            sample = next((ln for ln in self._lines[first + 1 : first + 6] if ln.strip()), "")
            self.decimal_comma = any(_DECIMAL_COMMA.match(c) for c in sample.split(";"))
        if report is not None:
            if self.ignored:
                what = [raw_header[i] or f"(unnamed #{i + 1})" for i in self.ignored]
                report.notes.append(f"unnamed columns ignored (pandas index / trailing separator): {what}")
            if self.delimiter != ",":
                report.notes.append(
                    f"{_DELIMITERS[self.delimiter]}-separated" + (", decimal comma" if self.decimal_comma else "")
                )

    def require(self, *names: str) -> None:
        missing = [n for n in names if n not in self.columns]
        if missing:
            raise InputError(
                f"{self.path}: missing required column(s) {missing}; header has "
                f"{', '.join(self.header[:10])}{', ...' if len(self.header) > 10 else ''}"
            )

    def rows(self) -> Iterator[tuple[int, list[str]]]:
        """(1-based line number, cells) for each non-blank data line. A short LAST row is skipped and
        reported; another row of the wrong length is a bad row (an error without a tolerance)."""
        body = self._lines[self._first + 1 :]
        last = max((k for k, ln in enumerate(body) if ln.strip()), default=-1)
        reader = csv.reader(body, delimiter=self.delimiter)
        for offset, cells in enumerate(reader):
            line = self._first + offset + 2
            if not cells or all(not c.strip() for c in cells):
                continue
            if len(cells) > self.width and all(not c.strip() for c in cells[self.width :]):
                cells = cells[: self.width]  # trailing separators
            if len(cells) != self.width:
                message = f"{self.path}: line {line}: {len(cells)} cells, expected {self.width} (one per header column)"
                if offset == last and len(cells) < self.width and self.report is not None:
                    self.report.skip("truncated last row")
                    continue
                if self.tolerance is None:
                    raise InputError(message)
                self.tolerance.handle(BadRow(message, f"rows with {len(cells)} of {self.width} cells"))
                continue
            if self.decimal_comma:
                cells = [c.replace(",", ".") for c in cells]
            yield line, cells

    def cell(self, cells: list[str], line: int, column: str) -> str:
        return cells[self.columns[column]].strip()

    def value(self, cells: list[str], line: int, column: str) -> float:
        """A cell as float: NaN if empty/NaN, BadRow for text or infinity."""
        text = self.cell(cells, line, column)
        try:
            value = parse_number(text)
        except ValueError as err:
            raise BadRow(f"{self.where(line, column)}: {text!r} is not a number", f"text in {column}") from err
        if math.isinf(value):
            raise BadRow(f"{self.where(line, column)}: {text!r} is not finite", f"infinite {column}")
        return value

    def number(self, cells: list[str], line: int, column: str, *, allow_empty: bool = False) -> float:
        """A finite float cell; NaN / inf / text raise InputError naming file, line and column."""
        value = self.value(cells, line, column)
        if math.isnan(value) and not allow_empty:
            raise BadRow(f"{self.where(line, column)}: empty or NaN, expected a finite number", f"empty {column}")
        return value

    def where(self, line: int, column: str) -> str:
        return f"{self.path}: line {line}, column {column!r} (#{self.columns[column] + 1})"
