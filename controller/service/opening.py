"""Opening a head for the service: the head profile, its calibration, the bus (a port or the emulated
chain), the configured driver, the pipeline (its gate tables built while torque is still off), then torque
on with goals pinned and the Bus Watchdog armed.

Start-up is part of the stop path (issue #9): the slow part (building the gate's tables, seconds on a first
run) runs inside :func:`~servoface.controller.stop_signals.interruptible`, so a Ctrl-C / SIGTERM / SIGHUP
there ends the start-up at once with torque never switched on; any failure after the driver exists ends with
torque off on every servo it can reach, then the bus (and the emulator) closed."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servoface.calibration import HeadCalibration, load_calibration
from servoface.controller import stop_signals
from servoface.controller.errors import ControllerError
from servoface.controller.head_servos import servo_specs, temperature_limits_c
from servoface.controller.pipeline import Pipeline
from servoface.hardware.bus import ServoBus, open_bus
from servoface.hardware.driver import Driver, FastSyncRead
from servoface.hardware.fault_policy import FaultPolicy
from servoface.sim.head import Head
from servoface.sim.heads import load_head


def head_calibration(head: Head, calibration: HeadCalibration | str | Path | None = None) -> HeadCalibration:
    """The calibration given, or the one the head profile names."""
    if isinstance(calibration, HeadCalibration):
        return calibration
    path = calibration if calibration is not None else head.calibration_path
    if path is None:
        raise ControllerError(
            f"head {head.name!r} names no calibration file; run `servoface calibrate --head ...` first"
        )
    if calibration is None and not Path(path).exists():  # a profile not calibrated yet: name the next step
        folder = head.profile_dir if head.profile_dir is not None else Path(path).parent
        raise ControllerError(
            f"head {head.name!r} has no calibration file {path} yet: run `servoface calibrate --head {folder} "
            f"--port /dev/ttyUSB0` (on the head), or `--csv {folder / 'calibration_template.csv'}` "
            f"(role,target,tick rows you measured), then `servoface check {folder}`"
        )
    return load_calibration(path)


@dataclass
class OpenedHead:
    """What :func:`open_head` built; ``chain`` is the emulated chain when emulating (else None)."""

    head: Head
    pipeline: Pipeline
    driver: Driver
    bus: ServoBus
    chain: Any = None

    def close(self) -> None:
        """Close the bus and the emulator (for a head never handed to a service)."""
        try:
            self.bus.close()
        finally:
            if self.chain is not None:
                self.chain.close()


def open_head(
    head: str | Path | Head = "human",
    *,
    port: str | None = None,
    baud: int = 1_000_000,
    emulate: bool = False,
    wire_time: bool = True,
    rate_hz: float = 50.0,
    calibration: HeadCalibration | str | Path | None = None,
    fast_sync_read: FastSyncRead = "auto",
    policy: FaultPolicy | None = None,
    position_sentinel: bool = True,
) -> OpenedHead:
    """Open ``head`` on ``port`` or on the emulator: servos configured from the profile and calibration
    (EEPROM only with torque off, limits written as a hardware backstop), the pipeline and its gate tables
    built, then torque on with goals pinned to present positions (Bus Watchdog armed, ``policy.watchdog_s``)
    and the pipeline starting from where the servos are. A stop signal before torque-on raises
    :class:`~servoface.controller.stop_signals.StopRequested`; on any failure every servo ends torque off.
    ``fast_sync_read``, ``policy`` and ``position_sentinel`` go to the `Driver`."""
    if (port is None) == (not emulate):
        raise ControllerError("Face.open: give exactly one of port='/dev/ttyUSB0' or emulate=True")
    the_head = head if isinstance(head, Head) else load_head(head)
    cal = head_calibration(the_head, calibration)
    specs = servo_specs(the_head, cal)
    chain = None
    if emulate:
        from servoface.hardware.emulator import ServoChain
        from servoface.hardware.emulator.chain import RUN_LOG_LIMIT

        chain = ServoChain.create(
            [(s.servo_id, s.model) for s in specs], baud=baud, wire_time=wire_time, log_limit=RUN_LOG_LIMIT
        )
        for s in specs:  # the head powers up at rest
            chain.servo(s.servo_id).move_by_hand(cal.by_id(s.servo_id).neutral_tick)
        bus = open_bus("dynamixel", port=chain, baud=baud)
    else:
        bus = open_bus("dynamixel", port=port, baud=baud)
    driver: Driver | None = None
    try:
        driver = Driver(bus, specs, fast_sync_read=fast_sync_read, policy=policy, position_sentinel=position_sentinel)
        driver.configure()
        with stop_signals.interruptible():  # torque is off and the bus idle: a signal aborts at once
            pipeline = Pipeline(  # builds the gate's tables (seconds on a first run) before torque goes on
                the_head, cal, driver=driver, rate_hz=rate_hz, temperature_limits_c=temperature_limits_c(specs)
            )
        stop_signals.raise_if_requested()
        driver.torque_on()  # goals pinned to present positions, then the Bus Watchdog armed
        snapshot = driver.read_state()
        lo_hi = cal.position_limits_tick()
        present = {sid: min(max(tick, lo_hi[sid][0]), lo_hi[sid][1]) for sid, tick in snapshot.positions_tick().items()}
        pipeline.pin_to(present)
        pipeline.last_snapshot = snapshot
        pipeline.last_write_s = pipeline.clock()  # goals were just pinned: the first frame's caps run from now
    except BaseException:
        try:
            if driver is not None:  # whatever went wrong, every servo ends with torque off
                driver.close(torque_off=True)
            else:
                bus.close()
        finally:
            if chain is not None:
                chain.close()
        raise
    return OpenedHead(the_head, pipeline, driver, bus, chain)
