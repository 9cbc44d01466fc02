"""Whether each actuator's range is one ``servoface calibrate`` can take, before the head is calibrated.

Until ticks are measured, the calibration template and ``calibrate --builtin`` assume an ideal servo: a
joint turns with it, 4096 ticks a turn, its neutral at tick 2048, reversed on the head's right side. They
refuse a range whose ends land outside goals 0..4095 or on one tick. ``check`` names such a range first,
with the key that sets it, by asking the same code (:func:`servoface.calibration.builtin.builtin_refusal`),
so it flags exactly the ranges calibrate refuses:

- a span of more than one turn or less than one tick: nearly always a typo (``[-200, 200]``, ``[0, 0.04]``);
- an end more than half a turn from neutral (``[0, 200]`` with neutral 0): the end that does not fit is
  named, with the fix (re-mount the horn, or move neutral or narrow the range).

A calibration that maps the range to ticks (a geared joint, or a horn mounted off-centre, measured with
``--csv`` or on the head) settles the question for its roles: they are not checked here.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING

from servoface.calibration.builtin import builtin_refusal
from servoface.calibration.curves import CENTRE_TICK, TICKS_PER_DEG, TICKS_PER_TURN
from servoface.calibration.servo import MAX_POSITION_TICK, MIN_POSITION_TICK

if TYPE_CHECKING:
    from servoface.calibration.spec import ServoSpec
    from servoface.sim.head import Head

MIN_SPAN_DEG = 1.0 / TICKS_PER_DEG  # one tick: 0.088 deg
MAX_SPAN_DEG = (MAX_POSITION_TICK - MIN_POSITION_TICK) / TICKS_PER_DEG  # 4095 ticks: 359.9 deg


def expected_span() -> str:
    """What a joint actuator's range must span, in words."""
    return (
        f"a span of {MIN_SPAN_DEG:.3f}..{MAX_SPAN_DEG:.1f} deg (1..{MAX_POSITION_TICK - MIN_POSITION_TICK} "
        f"ticks of a servo turning with the joint, {TICKS_PER_TURN} ticks a turn)"
    )


def expected_reach() -> str:
    """What a joint actuator's range must reach, in words."""
    return (
        f"both ends within {MIN_POSITION_TICK}..{MAX_POSITION_TICK} of a servo turning with the joint, its "
        f"neutral at tick {CENTRE_TICK} ({TICKS_PER_TURN} ticks a turn)"
    )


def _past(name: str, spec: ServoSpec, tick: int) -> str:
    """One end of a joint range that lands outside the goals: where, and the room on its side."""
    target = spec.upper if name == "upper" else spec.lower
    room = MAX_POSITION_TICK - CENTRE_TICK if tick > MAX_POSITION_TICK else CENTRE_TICK - MIN_POSITION_TICK
    limit = MAX_POSITION_TICK if tick > MAX_POSITION_TICK else MIN_POSITION_TICK
    return (
        f"the {name} end, {abs(target - spec.neutral):g} deg from neutral, lands on tick {tick}, past {limit}: "
        f"that side has {room} ticks ({room / TICKS_PER_DEG:.1f} deg)"
    )


def range_problem(spec: ServoSpec, where: str) -> str | None:
    """Why ``calibrate --template``/``--builtin`` refuse ``spec`` (a message starting with ``where``, the
    key that sets the range), or None when they take it."""
    refusal = builtin_refusal(spec)
    if refusal is None:
        return None
    got = f"for servo {spec.role!r}, got [{spec.lower:g}, {spec.upper:g}]"
    ends, span = refusal.ends, spec.upper - spec.lower
    if spec.kind == "joint" and ends is not None:
        if ends.outside and span > MAX_SPAN_DEG:
            return f"{where}: expected {expected_span()} {got} (spans {span:g} deg, more than one servo turn; a typo?)"
        if ends.lower == ends.upper:
            return f"{where}: expected {expected_span()} {got} (spans {span:g} deg, less than one servo tick; a typo?)"
        if ends.outside:
            past = "; ".join(_past(name, spec, getattr(ends, name)) for name in ends.outside)
            return (
                f"{where}: expected {expected_reach()} {got} with neutral {spec.neutral:g} deg ({past}; "
                "re-mount the horn so neutral sits nearer the middle of the travel and calibrate from measured "
                "ticks, or move the actuator's neutral_deg or narrow the range)"
            )
    return (
        f"{where}: servo {spec.role!r}, range [{spec.lower:g}, {spec.upper:g}] {spec.unit} with neutral "
        f"{spec.neutral:g}: `servoface calibrate` refuses it: {refusal.error}"
    )


def span_problems(head: Head, roles: Collection[str] | None = None) -> list[str]:
    """One message per actuator of ``head`` (only ``roles``, if given) whose range calibrate would refuse,
    naming the key that sets it (``head.toml: joint[1].limits_deg``), the range found and what it expects."""
    from servoface.controller.calibration_specs import specs_from_head  # the specs calibrate itself builds

    out = []
    for spec in specs_from_head(head):
        if roles is not None and spec.role not in roles:
            continue
        where = head.range_sources.get(spec.role) or f"actuator {spec.role!r}"
        if (why := range_problem(spec, where)) is not None:
            out.append(why)
    return out
