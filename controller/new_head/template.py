"""The calibration template: ``role,target,tick`` rows for every servo of a head, with an ideal servo's ticks.

Written by ``servoface new`` and, for a head.toml edited since (a servo added or taken out, a range
changed), by ``servoface calibrate --head DIR --template``. The builder replaces the ticks by what they
measure and runs ``servoface calibrate --head DIR --csv DIR/calibration_template.csv``. Rows: the lower
limit, neutral, the upper limit and points between, per servo in the profile's order; one row per tick for
a range of only a few ticks (ticks must be strictly monotone in the target), so that ``--csv`` takes the
unedited template whenever ``--builtin`` takes the range.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from servoface.calibration.spec import ServoSpec

TEMPLATE_CSV = "calibration_template.csv"
POINTS_PER_SERVO = 5  # lower, upper and three between (plus neutral when it is not one of them)
TARGET_PLACES = 3  # decimals of a row's target

HEADER = (
    "# role,target,tick: the Present Position (tick) you read when the actuator is at target (deg or mm).",
    "# These ticks are an IDEAL servo's (2048 = neutral): measure yours and replace them (jog the servo,",
    "# read the tick with the Dynamixel Wizard or `servoface calibrate --port ...`). Ticks must be strictly",
    "# monotone in the target. Then: servoface calibrate --head DIR --csv DIR/calibration_template.csv",
    "role,target,tick",
)


def template_text(head_name: str, specs: Sequence[ServoSpec]) -> str:
    """The template's text for ``specs`` (CalibrationError, naming the servo, when an ideal servo cannot
    reach a range: more than one turn, an end past 0..4095, or both ends on one tick)."""
    import numpy as np
    from servoface.calibration.builtin import builtin_calibration

    cal = builtin_calibration(head_name, specs)
    lines = list(HEADER)
    for spec in specs:
        servo = cal[spec.role]
        # targets as typed (3 decimals), more for a range under 0.1 (mm): an end row stays within 1% of its end
        places = TARGET_PLACES + max(0, math.ceil(math.log10(0.1 / (spec.upper - spec.lower))))
        ends = np.linspace(spec.lower, spec.upper, POINTS_PER_SERVO).round(places).tolist()
        neutral = float(np.round(spec.neutral, places))
        targets = sorted({*ends, neutral})
        # rounding moves an end's row a little past the range (25.0006 -> 25.001) or short of it: give it the
        # end's own tick (the built-in calibration's limit), so the template refuses no range that one takes
        ticks = {t: servo.to_tick(min(max(float(t), spec.lower), spec.upper)) for t in targets}
        ticks[targets[0]], ticks[targets[-1]] = servo.to_tick(spec.lower), servo.to_tick(spec.upper)
        # a range of a few ticks puts rows on one tick (0..0.05 deg: 2048, 2048, ...), which --csv refuses as
        # not strictly monotone: keep one row per tick, the ends first (coverage), then neutral, then between
        kept: dict[int, float] = {}
        for t in (targets[0], targets[-1], neutral, *targets):
            kept.setdefault(ticks[t], t)
        for t in sorted(kept.values()):
            lines.append(f"{spec.role},{t:.15g},{ticks[t]}")  # every digit kept (:g cuts 1000.044 to 1000.04)
    return "\n".join(lines) + "\n"


def write_template(head_name: str, specs: Sequence[ServoSpec], out: Path) -> Path:
    """Write the template to ``out`` atomically (a reader sees the old file or the new one, never half)."""
    from servoface.calibration.fileformat import write_atomic

    return write_atomic(Path(out), template_text(head_name, specs))


def write_template_csv(head_dir: Path, out: Path | None = None) -> Path:
    """``calibration_template.csv`` (or ``out``) for the profile in ``head_dir``, replacing any file there."""
    from servoface.controller.calibration_specs import specs_from_head
    from servoface.sim.heads import load_head

    head = load_head(head_dir)
    return write_template(head.name, specs_from_head(head), Path(head_dir) / TEMPLATE_CSV if out is None else out)
