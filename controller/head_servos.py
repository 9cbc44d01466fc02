"""A head's servos as the driver needs them: one `ServoSpec` per actuator, limits from the calibration.

The servo-side Min/Max Position Limits are written from the calibration (widened by a small margin so the
backstop never fights a legal goal): the last safety layer under the twin gate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

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


MismatchKind = Literal["missing", "extra", "id", "model"]


@dataclass(frozen=True)
class CalibrationMismatch:
    """One place where a calibration and the head profile disagree. ``missing``: a profile role the
    calibration has no servo for; ``extra``: a calibrated role the profile does not have; ``id`` and
    ``model``: the role's servo id or model, ``profile`` and ``calibration`` as each writes it."""

    kind: MismatchKind
    role: str
    profile: str = ""
    calibration: str = ""


def calibration_mismatches(head: Head, calibration: HeadCalibration) -> list[CalibrationMismatch]:
    """Every difference between ``calibration`` and ``head``'s actuators, in profile order (missing roles,
    then the calibration's extra roles, then per role its id and its model). Models are compared by the
    driver's name (``MX-28`` is ``MX-28(2.0)``); one the driver does not know is compared as written.
    The one reading shared by `servo_specs` (opening the head), the commands' calibration check and
    ``servoface check``'s list."""
    found = [CalibrationMismatch("missing", a.role) for a in head.actuators if a.role not in calibration.roles]
    found += [CalibrationMismatch("extra", r) for r in calibration.roles if r not in head.roles]
    for a in head.actuators:
        if a.role not in calibration.roles:
            continue
        c = calibration[a.role]
        if c.servo_id != a.servo.id:
            found.append(CalibrationMismatch("id", a.role, str(a.servo.id), str(c.servo_id)))
        if not same_model(a.servo.model, c.model):
            found.append(CalibrationMismatch("model", a.role, a.servo.model, c.model))
    return found


def same_model(a: str, b: str) -> bool:
    """Whether two model names written in profiles or calibrations name the same servo model."""
    try:
        return driver_model_name(a) == driver_model_name(b)
    except KeyError:
        return a == b


def servo_specs(
    head: Head, calibration: HeadCalibration, *, return_delay_us: int = 0, margin_tick: int = 8
) -> list[ServoSpec]:
    """One ServoSpec per actuator of ``head``, in actuator order, checked against the calibration: every
    role calibrated, with the profile's servo id and model (a calibration measured on another servo model
    is refused: its ticks were read from other servos), and a model the driver knows."""
    for m in calibration_mismatches(head, calibration):
        if m.kind == "missing":
            raise HeadProfileError(f"head {head.name!r}: calibration has no servo for role {m.role!r}")
        if m.kind == "id":
            raise HeadProfileError(
                f"head {head.name!r}: role {m.role!r} is servo id {m.profile} in the profile but "
                f"{m.calibration} in the calibration"
            )
        if m.kind == "model":
            raise HeadProfileError(
                f"head {head.name!r}: role {m.role!r} is servo model {m.profile} in the profile but {m.calibration} "
                f"in the calibration: fix actuators.{m.role}.servo.model or recalibrate the role"
            )
    specs: list[ServoSpec] = []
    limits = calibration.position_limits_tick(margin_tick)
    for actuator in head.actuators:
        role = actuator.role
        cal = calibration[role]
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
