"""What a reader made of a file, for the user: rows used / filled / skipped (with reasons), cells clamped or
filled, columns ignored, the time unit and frame rate it settled on, the faces it saw and which one it
followed, the rest pose it took. ``Recording.report`` carries it; ``servoface play --input`` and
``servoface preview --input`` print :meth:`InputReport.lines`."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field


@dataclass
class InputReport:
    """Per-file summary of a read (see the module doc). ``rows`` = frames made (used + held)."""

    source: str
    reader: str = ""
    rows: int = 0
    held: int = 0  # rows the lost-tracking policy filled (tracking failed / low confidence / no face)
    skipped: Counter[str] = field(default_factory=Counter)  # reason -> rows left out
    cells_clamped: int = 0  # values slightly outside their range (within the tolerance), clamped
    cells_filled: int = 0  # single empty/NaN cells filled with that channel's previous value
    columns_ignored: list[str] = field(default_factory=list)
    time: str = ""  # e.g. "timestamp in ms (detected: steps of 33.3 = 30.0 fps)"
    fps: float | None = None
    faces: str = ""  # e.g. "2 faces (face_id 0, 1); followed face_id 0"
    rest: str = ""  # e.g. "rest pose from the first 2 s (60 rows): eyeSquintLeft 0.61, ..."
    notes: list[str] = field(default_factory=list)

    def skip(self, reason: str, count: int = 1) -> None:
        self.skipped[reason] += count

    @property
    def used(self) -> int:
        return self.rows - self.held

    def lines(self) -> list[str]:
        """Human-readable lines, the first one the headline."""
        head = f"{self.source}: {self.reader or 'read'}: {self.used} rows used"
        head += f", {self.held} filled by the lost-tracking policy" if self.held else ""
        head += f", {sum(self.skipped.values())} skipped" if self.skipped else ""
        out = [head]
        out += [f"  skipped {n} x {reason}" for reason, n in self.skipped.most_common()]
        if self.time:
            out.append(f"  time: {self.time}")
        if self.faces:
            out.append(f"  faces: {self.faces}")
        if self.cells_clamped:
            out.append(f"  {self.cells_clamped} values slightly outside their range clamped (tolerance 10 % of range)")
        if self.cells_filled:
            out.append(f"  {self.cells_filled} empty/NaN cells filled with the previous row's value")
        if self.columns_ignored:
            shown = ", ".join(self.columns_ignored[:8]) + (", ..." if len(self.columns_ignored) > 8 else "")
            out.append(f"  columns ignored ({len(self.columns_ignored)}): {shown}")
        if self.rest:
            out.append(f"  {self.rest}")
        out += [f"  note: {n}" for n in self.notes]
        return out
