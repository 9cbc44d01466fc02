"""How forgiving the readers are, in one place (README "Inputs", "Tolerances").

* A value within ``SLACK`` (10 %) of its range's span beyond the range (a Live Link Face ``eyeLookInRight``
  of 1.0033, a py-feat ``-1e-7``, an OpenFace AU of 5.2) is clamped into the range and counted.
* Beyond that, or text where a number belongs, the row is bad: ``bad_rows="skip"`` (default) leaves it out
  and counts the reason, ``bad_rows="error"`` raises :class:`InputError` naming file, line and column.
  A file where more than half the rows are bad is refused either way (the wrong file or the wrong reader).
* One empty / NaN value cell is filled with that channel's previous value (0 before the first) and counted;
  a row whose value cells are all empty is "no face" and goes to the lost-tracking policy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.report import InputReport

SLACK = 0.1  # fraction of a range's span a value may overshoot and still be clamped
BAD_ROWS = ("skip", "error")


class BadRow(InputError):
    """A row that cannot be used; ``reason`` is the short, countable why (``"AU12_r 9 outside 0..5"``)."""

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass
class Tolerance:
    """The policy above, with the counters it updates on ``report``."""

    report: InputReport
    bad_rows: str = "skip"
    slack: float = SLACK
    bad: int = 0
    first_bad: str = ""  # the first bad row's message (file, line, column or field): named when refusing

    def __post_init__(self) -> None:
        if self.bad_rows not in BAD_ROWS:
            raise InputError(f"bad_rows: expected one of {BAD_ROWS}, got {self.bad_rows!r}")

    def ranged(self, value: float, lo: float, hi: float, *, where: str, what: str) -> float:
        """``value`` clamped into lo..hi if within the slack, else BadRow."""
        if lo <= value <= hi:
            return value
        pad = self.slack * (hi - lo)
        if lo - pad <= value <= hi + pad:
            self.report.cells_clamped += 1
            return min(hi, max(lo, value))
        raise BadRow(
            f"{where}: {value:g} is outside {what} {lo:g}..{hi:g} (more than {self.slack:.0%} of the range beyond)",
            f"{what} outside {lo:g}..{hi:g}",
        )

    def handle(self, err: BadRow) -> None:
        """A bad row: raise it (``bad_rows="error"``) or count it as skipped."""
        if self.bad_rows == "error":
            raise InputError(str(err)) from err
        self.bad += 1
        self.first_bad = self.first_bad or str(err)
        self.report.skip(err.reason)

    def check_share(self, total_rows: int, *, excluding: int = 0) -> None:
        """Refuse the file when more than half its rows are bad (``excluding`` bad rows that do not count:
        rows whose time goes back, which a frame rate that contradicts the file makes)."""
        bad = self.bad - excluding
        if total_rows and bad * 2 > total_rows:
            reasons = "; ".join(f"{n} x {r}" for r, n in self.report.skipped.most_common(3))
            first_bad = self.first_bad.removeprefix(f"{self.report.source}: ")
            first = f"; the first: {first_bad[:300]}" if first_bad else ""
            raise InputError(
                f"{self.report.source}: {bad} of {total_rows} rows are unusable ({reasons}){first}; "
                "is this the right file for this reader?"
            )


def parse_number(text: str) -> float:
    """A cell as a float: NaN for empty / ``nan`` / ``NA``; ValueError for text; inf stays inf (the caller
    decides)."""
    t = text.strip()
    if not t or t.lower() in ("nan", "na", "n/a", "null", "none"):
        return math.nan
    return float(t)
