"""Whether each joint actuator's range is one a servo can be calibrated on, before it is calibrated.

A servo in position mode reads 4096 ticks a turn and takes goals 0..4095, so a joint it turns with it (as
the calibration template and ``servoface calibrate`` assume until ticks are measured) must span at least
one tick (360/4096 deg) and at most 4095 ticks (359.9 deg). A span outside that is nearly always a typo
in head.toml (``[-200, 200]``, ``[0, 0.04]``); ``calibrate`` refuses it, so ``check`` names it first,
with the key that sets the range. A calibration that maps the range to ticks (a geared joint measured
with ``--csv``) settles the question for its roles: they are not checked here.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING

from servoface.calibration.curves import TICKS_PER_DEG
from servoface.calibration.servo import MAX_POSITION_TICK, MIN_POSITION_TICK

if TYPE_CHECKING:
    from servoface.sim.head import Head

MIN_SPAN_DEG = 1.0 / TICKS_PER_DEG  # one tick: 0.088 deg
MAX_SPAN_DEG = (MAX_POSITION_TICK - MIN_POSITION_TICK) / TICKS_PER_DEG  # 4095 ticks: 359.9 deg


def expected_span() -> str:
    """What a joint actuator's range must span, in words."""
    return (
        f"a span of {MIN_SPAN_DEG:.3f}..{MAX_SPAN_DEG:.1f} deg (1..{MAX_POSITION_TICK - MIN_POSITION_TICK} "
        f"ticks of a servo turning with the joint, {round(360 * TICKS_PER_DEG)} ticks a turn)"
    )


def span_problem(lower_deg: float, upper_deg: float) -> str | None:
    """Why a joint range ``lower_deg..upper_deg`` cannot be calibrated on one servo turn (None: it can)."""
    span = upper_deg - lower_deg
    if span > MAX_SPAN_DEG:
        return f"spans {span:g} deg, more than one servo turn"
    if span < MIN_SPAN_DEG:
        return f"spans {span:g} deg, less than one servo tick"
    return None


def span_problems(head: Head, roles: Collection[str] | None = None) -> list[str]:
    """One message per joint actuator of ``head`` (only ``roles``, if given) whose range cannot be
    calibrated, naming the key that sets it (``head.toml: joint[1].limits_deg``), the range found and the
    span expected."""
    out = []
    for a in head.joint_actuators:
        if roles is not None and a.role not in roles:
            continue
        why = span_problem(a.lower_deg, a.upper_deg)
        if why is None:
            continue
        where = head.range_sources.get(a.role) or f"actuator {a.role!r}"
        out.append(
            f"{where}: expected {expected_span()} for servo {a.role!r}, got [{a.lower_deg:g}, {a.upper_deg:g}] "
            f"({why}; a typo?)"
        )
    return out
