"""A new calibration, used at once by the running head (no restart): the same objects the service drives
with, replaced together between two frames.

1. :func:`complete`: the new calibration for every servo of the head (roles it does not name keep the
   running calibration's), in the running calibration's column order.
2. :func:`prepare` (any thread, seconds): the twin gate for it, built while the loop still runs.
3. :func:`install` (on the bus lender, the loop paused between two frames): the driver's servo specs get
   the new position limits and are written (torque off, EEPROM, read back), the pipeline takes the new
   calibration and gate (:meth:`~servoface.controller.pipeline.Pipeline.use_calibration`: last command
   clamped into the new limits), torque comes back as it was; on resume the service re-pins its goals to
   the wire, clamped into the new limits, so nothing jumps.
The twin renderer is told afterwards (its own process, its own copy)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from servoface.calibration import HeadCalibration
from servoface.controller.head_servos import servo_specs
from servoface.controller.service import HeadService
from servoface.hardware.driver import Driver


@dataclass(frozen=True)
class Prepared:
    calibration: HeadCalibration
    gate: Any
    specs: list[Any]


def complete(new: HeadCalibration, running: HeadCalibration) -> HeadCalibration:
    servos = [new[r] if r in new.roles else running[r] for r in running.roles]
    return HeadCalibration(running.head, servos, new.metadata)


def prepare(service: HeadService, new: HeadCalibration) -> Prepared:
    from servoface.sim.gate import TwinGate

    pipeline = service.pipeline
    cal = complete(new, pipeline.calibration)
    specs = servo_specs(service.head, cal)  # checks roles and ids against the head profile
    old = pipeline.gate
    gate = TwinGate(service.head, cal, old.frame_period_s, old.config, face_model=pipeline.face)
    return Prepared(cal, gate, specs)


def install(service: HeadService, prepared: Prepared, driver: Driver, torque_wanted: Callable[[], bool]) -> None:
    """On the thread that owns the driver, the loop paused."""
    driver.respec(prepared.specs)
    try:
        driver.configure()  # torque off; the new limits in EEPROM as the hardware backstop
        service.pipeline.use_calibration(prepared.calibration, prepared.gate)
    finally:
        if torque_wanted():
            driver.torque_on()  # goals pinned to where the servos are, clamped into the (new) limits
