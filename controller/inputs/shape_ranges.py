"""Per-user rest/range calibration of blendshape scores.

Trackers under-report some shapes for some faces (MediaPipe's eyeWide and noseSneer rarely exceed 0.05,
mediapipe #4450) and others never return to 0 at rest; facs-human.md §3-4 recommends a per-user rest and
range. ``ShapeRanges`` rescales each listed shape: ``score' = clamp((score - rest) / (full - rest), 0, 1)``;
unlisted shapes pass unchanged. Build one from a short recording of the user (neutral, then the widest
expressions they will make) with :meth:`ShapeRanges.from_samples`, save it as JSON, and pass it to
``MessageDecoder(shape_ranges=...)`` or ``servoface stream --shape-ranges FILE``.

JSON: ``{"schema_version": 1, "ranges": {"eyeWideLeft": [0.0, 0.06], "mouthSmileLeft": [0.05, 0.9]}}``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servoface.controller.inputs.csv_table import read_text
from servoface.controller.inputs.errors import InputError

MAX_RANGES_BYTES = 1024 * 1024  # a ranges file is a few kB
MIN_SPAN = 0.01  # a range narrower than this would turn tracker noise into full-scale motion


@dataclass(frozen=True)
class ShapeRanges:
    """Shape name -> (rest, full) score."""

    ranges: Mapping[str, tuple[float, float]]

    def __post_init__(self) -> None:
        for name, pair in self.ranges.items():
            check_range(name, pair, where="ranges")

    def apply(self, scores: Mapping[str, float]) -> dict[str, float]:
        out = dict(scores)
        for name, score in scores.items():
            pair = self.ranges.get(name)
            if pair is not None:
                rest, full = pair
                out[name] = min(1.0, max(0.0, (score - rest) / (full - rest)))
        return out

    @classmethod
    def from_samples(
        cls, samples: Sequence[Mapping[str, float]], *, rest_pct: float = 5.0, full_pct: float = 99.0
    ) -> ShapeRanges:
        """Ranges from recorded raw scores: rest = the ``rest_pct`` percentile, full = the ``full_pct`` one
        (robust to a few outliers). Shapes whose span is below ``MIN_SPAN`` are left out (never moved)."""
        columns: dict[str, list[float]] = {}
        for sample in samples:
            for name, value in sample.items():
                columns.setdefault(name, []).append(float(value))
        ranges: dict[str, tuple[float, float]] = {}
        for name, values in columns.items():
            values.sort()
            rest, full = _percentile(values, rest_pct), _percentile(values, full_pct)
            if full - rest >= MIN_SPAN:
                ranges[name] = (rest, full)
        return cls(ranges)

    def save(self, path: str | Path) -> None:
        """Write the JSON atomically (a temp file beside ``path``, fsynced, renamed over it): a reader, or a
        run killed mid-write, sees the old file or the new one, never an empty or half-written one."""
        from servoface.calibration.fileformat import write_atomic

        data = {
            "schema_version": 1,
            "ranges": {k: [round(a, 6), round(b, 6)] for k, (a, b) in self.ranges.items()},
        }
        try:
            write_atomic(Path(path), json.dumps(data, indent=1, sort_keys=True) + "\n")
        except OSError as err:
            raise InputError(f"shape ranges {path}: cannot write: {err}") from err

    @classmethod
    def load(cls, path: str | Path, known: frozenset[str] | None = None) -> ShapeRanges:
        """Read a ranges JSON; ``known`` (the blendshape names) makes unknown names an error."""
        file = Path(path)
        try:
            data = json.loads(
                read_text(file, max_bytes=MAX_RANGES_BYTES, what="a shape ranges file")
            )  # never /dev/zero into memory
        except (InputError, ValueError, RecursionError) as err:  # RecursionError: JSON nested 10^5 deep
            raise InputError(f"{file}: cannot read shape ranges: {str(err).removeprefix(f'{file}: ')}") from err
        if not isinstance(data, dict) or data.get("schema_version") != 1 or not isinstance(data.get("ranges"), dict):
            raise InputError(f'{file}: expected {{"schema_version": 1, "ranges": {{shape: [rest, full]}}}}')
        ranges: dict[str, tuple[float, float]] = {}
        for name, pair in data["ranges"].items():
            if known is not None and name not in known:
                raise InputError(f"{file}: ranges.{name}: not a blendshape name")
            ranges[name] = check_range(name, pair, where=f"{file}: ranges")
        return cls(ranges)


def check_range(name: str, pair: Any, *, where: str) -> tuple[float, float]:
    ok = isinstance(pair, list | tuple) and len(pair) == 2
    ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in pair)
    if not ok or not (0.0 <= pair[0] and pair[0] + MIN_SPAN <= pair[1] <= 1.0):
        raise InputError(
            f"{where}.{name}: expected [rest, full], 0 <= rest, rest + {MIN_SPAN} <= full <= 1, got {pair!r}"
        )
    return float(pair[0]), float(pair[1])


def _percentile(sorted_values: list[float], pct: float) -> float:
    index = min(len(sorted_values) - 1, max(0, round(pct / 100.0 * (len(sorted_values) - 1))))
    return sorted_values[index]
