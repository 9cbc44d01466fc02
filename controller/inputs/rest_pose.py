"""The user's rest pose from the first N seconds of a take (``rest_s`` / ``--rest-s``).

Trackers do not read 0 at rest for every face: MediaPipe's ``eyeSquint`` rests at 0.49-0.76 and ``eyeBlink``
at 0.26-0.34 for some users, OpenFace's AU intensities carry per-person offsets, and a head pose is relative
to where the camera stands. Ask the user to hold a neutral face for the first N seconds; then per channel
the median over that window is the rest: a score becomes ``clamp((v - rest) / (1 - rest), 0, 1)`` (a
blendshape: merged into the shape ranges, an explicit range wins), head and gaze angles are taken relative
to the rest angles. Channels resting below ``MIN_REST`` are left alone (no reason to rescale noise).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.shape_ranges import MIN_SPAN, ShapeRanges

MIN_REST = 0.02

_Row = tuple[float, Mapping[str, float] | None, tuple[float, float, float] | None, tuple[float, float] | None]


@dataclass(frozen=True)
class RestPose:
    values: dict[str, float]  # channel -> rest score (only those >= MIN_REST)
    head_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gaze_deg: tuple[float, float] = (0.0, 0.0)
    rows: int = 0

    @classmethod
    def from_rows(cls, rows: Sequence[_Row], rest_s: float) -> RestPose:
        """From (t_s, values or None, head or None, gaze or None) rows, times from the first row."""
        if not rows:
            raise InputError("rest pose: no rows")
        t0 = rows[0][0]
        window = [r for r in rows if r[0] - t0 <= rest_s and r[1] is not None]
        if not window:
            raise InputError(f"rest pose: no tracked rows in the first {rest_s:g} s to take the rest pose from")
        columns: dict[str, list[float]] = {}
        for _, values, _, _ in window:
            for k, v in (values or {}).items():
                columns.setdefault(k, []).append(v)
        rest = {k: statistics.median(v) for k, v in columns.items()}
        rest = {k: min(v, 1.0 - MIN_SPAN) for k, v in rest.items() if v >= MIN_REST}
        heads = [r[2] for r in window if r[2] is not None]
        gazes = [r[3] for r in window if r[3] is not None]
        head = tuple(statistics.median(h[i] for h in heads) for i in range(3)) if heads else (0.0, 0.0, 0.0)
        gaze = tuple(statistics.median(g[i] for g in gazes) for i in range(2)) if gazes else (0.0, 0.0)
        return cls(rest, head, gaze, len(window))  # type: ignore[arg-type]

    def rescale(self, values: Mapping[str, float]) -> dict[str, float]:
        out = dict(values)
        for k, rest in self.values.items():
            if k in out:
                out[k] = min(1.0, max(0.0, (out[k] - rest) / (1.0 - rest)))
        return out

    def shape_ranges(self, given: ShapeRanges | None) -> ShapeRanges:
        ranges = {k: (rest, 1.0) for k, rest in self.values.items()}
        if given is not None:
            ranges.update(given.ranges)
        return ShapeRanges(ranges)

    def head(self, ypr: tuple[float, float, float]) -> tuple[float, float, float]:
        return (ypr[0] - self.head_deg[0], ypr[1] - self.head_deg[1], ypr[2] - self.head_deg[2])

    def gaze(self, yp: tuple[float, float]) -> tuple[float, float]:
        return (yp[0] - self.gaze_deg[0], yp[1] - self.gaze_deg[1])

    def describe(self, rest_s: float) -> str:
        top = sorted(self.values.items(), key=lambda kv: -kv[1])[:5]
        shown = ", ".join(f"{k} {v:.2f}" for k, v in top) or "no channel above rest"
        head = ", head yaw/pitch/roll {:.1f}/{:.1f}/{:.1f} deg".format(*self.head_deg) if any(self.head_deg) else ""
        return f"rest pose from the first {rest_s:g} s ({self.rows} rows): {shown}{head}"
