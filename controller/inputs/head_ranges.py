"""Measured input (tracker files, live streams) saturated to what one head can show.

A tracker measures a person: a full smile is AU12 = 1 whatever the robot. A head's own AU table may give an
AU a narrower range (its lip corners reach half a smile: ``range = [0.0, 0.5]``). Authored content (an
expression, a script) outside that range is refused, since its author asked for what the head cannot do. A
measurement is not an instruction: it is saturated to the head's range and counted, so the robot smiles as far
as it can and the performance goes on. Everything else about a value (a name, a non-finite number, a value
outside the face type's own range) is checked where it is read, and refused there.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from servoface.controller.au_names import head_au_ranges, intensity_range
from servoface.controller.frame import AUFrame
from servoface.controller.inputs.recorded import Recording
from servoface.sim.rig import FaceType


@dataclass(frozen=True)
class HeadRanges:
    """The AU ranges of one head where they are narrower than its face type's (``narrow``: name -> (lo, hi))."""

    head: str
    face_type: FaceType
    narrow: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    @classmethod
    def of(cls, head: Any) -> HeadRanges:
        """The ranges of a loaded head (``servoface.sim.head.Head``): its own AU table, else its face type's."""
        face_type: FaceType = head.face_type
        lo, hi = intensity_range(face_type)
        narrow = {n: r for n, r in head_au_ranges(head).items() if r[0] > lo or r[1] < hi}
        return cls(str(head.name), face_type, narrow)

    def saturate(self, aus: Mapping[str, float]) -> tuple[dict[str, float], list[str]]:
        """(``aus`` with every value held inside its range on this head, the names whose value was moved)."""
        out = dict(aus)
        moved: list[str] = []
        for name, value in aus.items():
            rng = self.narrow.get(name)
            if rng is not None and not rng[0] <= value <= rng[1]:
                out[name] = min(rng[1], max(rng[0], value))
                moved.append(name)
        return out, moved

    def describe(self, counts: Mapping[str, int]) -> str:
        """One line for the user: how many values were saturated, per AU with its range on this head."""
        total = sum(counts.values())
        per_au = ", ".join(
            f"{name} {n} x ({_num(self.narrow[name][0])}..{_num(self.narrow[name][1])})"
            for name, n in sorted(counts.items(), key=lambda item: (-item[1], item[0]))
        )
        return f"{total} values beyond the AU ranges of head '{self.head}' held at their ends: {per_au}"


def fit_recording(recording: Recording, ranges: HeadRanges) -> Recording:
    """``recording`` with its frames saturated to the head's ranges (itself when nothing is outside them); the
    count goes into the new recording's report as a note (``recording`` is not changed)."""
    counts: Counter[str] = Counter()
    frames = []
    for frame in recording.frames:
        aus, moved = ranges.saturate(frame.aus)
        counts.update(moved)
        frames.append(AUFrame(frame.t_s, aus, frame.face_type) if moved else frame)
    if not counts:
        return recording
    # a report of its own: the caller's recording is left as it was (played twice, it is not noted twice)
    report = replace(recording.report, notes=[*recording.report.notes, ranges.describe(counts)])
    return Recording(
        frames, recording.face_type, interpolate=recording.interpolate, source=recording.source, report=report
    )


def _num(value: float) -> str:
    return f"{value:g}"
