"""A head's servos as the driver needs them: one `ServoSpec` per actuator, limits from the calibration.

The servo-side Min/Max Position Limits are written from the calibration (widened by a small margin so the
backstop never fights a legal goal): the last safety layer under the twin gate.
"""

from __future__ import annotations

from servoface.calibration import HeadCalibration
from servoface.hardware.registers import model_by_name
from servoface.hardware.servo_config import ServoSpec
from servoface.sim.errors import HeadProfileError
from servoface.sim.head import Head

# Head profiles may use the short catalogue name; the driver names the Protocol 2.0 firmware explicitly.
_MODEL_ALIASES = {"MX-28": "MX-28(2.0)", "MX-28-2.0": "MX-28(2.0)"}


def driver_model_name(model: str) -> str:
    """The driver's name for a model written in a head profile or calibration file."""
    name = _MODEL_ALIASES.get(model.strip().upper(), model)
    model_by_name(name)  # raises KeyError naming the known models
    return name


def servo_specs(
    head: Head, calibration: HeadCalibration, *, return_delay_us: int = 0, margin_tick: int = 8
) -> list[ServoSpec]:
    """One ServoSpec per actuator of ``head``, in actuator order, checked against the calibration."""
    specs: list[ServoSpec] = []
    limits = calibration.position_limits_tick(margin_tick)
    for actuator in head.actuators:
        role = actuator.role
        if role not in calibration.roles:
            raise HeadProfileError(f"head {head.name!r}: calibration has no servo for role {role!r}")
        cal = calibration[role]
        if cal.servo_id != actuator.servo.id:
            raise HeadProfileError(
                f"head {head.name!r}: role {role!r} is servo id {actuator.servo.id} in the profile but "
                f"{cal.servo_id} in the calibration"
            )
        try:
            model = driver_model_name(actuator.servo.model)
        except KeyError as err:
            raise HeadProfileError(f"head {head.name!r}: actuators.{role}.servo.model: {err}") from err
        lo, hi = limits[cal.servo_id]
        specs.append(
            ServoSpec(
                servo_id=cal.servo_id,
                model=model,
                role=role,
                min_position_tick=lo,
                max_position_tick=hi,
                return_delay_us=return_delay_us,
            )
        )
    return specs


def temperature_limits_c(specs: list[ServoSpec]) -> dict[int, float]:
    """id -> the temperature limit the servo works to (its spec's, else the model's default)."""
    return {
        s.servo_id: float(s.temperature_limit_c or model_by_name(s.model).default_temperature_limit_c) for s in specs
    }
