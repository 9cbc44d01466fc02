"""Calibration's view of a head's actuators: one `servoface.calibration.spec.ServoSpec` per actuator (role,
servo, unit, range, neutral, kind, default direction). What `calibrate`, `check`'s reach rule
(`servoface.controller.joint_spans`), the calibration template and the studio's calibration page share."""

from __future__ import annotations

from typing import Any

from servoface.calibration.spec import ServoSpec


def specs_from_head(head: Any) -> list[ServoSpec]:
    """Calibration's view of a head's actuators (servoface.sim.head.Head -> servoface.calibration.spec.ServoSpec)."""
    from servoface.calibration.spec import default_direction
    from servoface.sim.rig import JointActuator

    specs = []
    for a in head.actuators:
        direction = default_direction(a.role)
        if isinstance(a, JointActuator):
            specs.append(
                ServoSpec(
                    a.role,
                    a.servo.id,
                    a.servo.model,
                    "deg",
                    a.lower_deg,
                    a.upper_deg,
                    a.neutral_deg,
                    "joint",
                    direction,
                )
            )
        else:
            specs.append(
                ServoSpec(
                    a.role,
                    a.servo.id,
                    a.servo.model,
                    "mm",
                    a.lower_mm,
                    a.upper_mm,
                    a.neutral_mm,
                    "anchor",
                    direction,
                )
            )
    return specs
