"""Whether each actuator's range is one ``servoface calibrate`` can take, before the head is calibrated.

Until ticks are measured, the calibration template and ``calibrate --builtin`` assume an ideal servo: a
joint turns with it, 4096 ticks a turn, its neutral at tick 2048, reversed on the head's right side. They
refuse a range whose ends land outside goals 0..4095 or on one tick. ``check`` names such a range first,
with the key that sets it, by asking the same code (:func:`servoface.calibration.builtin.builtin_refusal`),
so it flags exactly the ranges calibrate refuses:

- a span of more than one turn, or ends that land on one tick: nearly always a typo (``[-200, 200]``,
  ``[0, 0.04]``); for one tick, the fix (widen the range, or gear the joint and calibrate from measured ticks);
- an end more than half a turn from neutral (``[0, 200]`` with neutral 0): the end that does not fit is
  named, with the fix (re-mount the horn, or move neutral or narrow the range).

The words are calibrate's own (:func:`servoface.calibration.builtin.reach_problem`), after the key.

A calibration that maps the range to ticks (a geared joint, or a horn mounted off-centre, measured with
``--csv`` or on the head) settles the question for its roles: they are not checked here.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import TYPE_CHECKING

from servoface.calibration.builtin import builtin_refusal

if TYPE_CHECKING:
    from servoface.calibration.spec import ServoSpec
    from servoface.sim.head import Head


def range_problem(spec: ServoSpec, where: str) -> str | None:
    """Why ``calibrate --template``/``--builtin`` refuse ``spec`` (a message starting with ``where``, the
    key that sets the range), or None when they take it. A joint range the ideal servo cannot reach is
    named in calibrate's own words (:func:`servoface.calibration.builtin.reach_problem`) after the key."""
    refusal = builtin_refusal(spec)
    if refusal is None:
        return None
    if refusal.reason is not None:
        return f"{where}: {refusal.reason}"
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
