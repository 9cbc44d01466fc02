"""From a resolved config to the servos under test: the head (profile + calibration), one `ServoSpec` per
servo (the driver's description: limits, model, role) and the `ChainSpec` to emulate them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servoface.testing.chains import ChainSpec
from servoface.testing.config import ServofaceConfig
from servoface.testing.limits import WireLimits


@dataclass(frozen=True)
class Rig:
    """The servos of one test. ``head``/``calibration`` are None for an explicit servo list."""

    specs: tuple[Any, ...]  # servoface.hardware.servo_config.ServoSpec
    head: Any = None  # servoface.sim.head.Head
    calibration: Any = None  # servoface.calibration.HeadCalibration

    def chain_spec(self, config: ServofaceConfig) -> ChainSpec:
        """The emulated chain: the specs' ids and models; a head powers up at its calibrated neutral."""
        positions = {}
        if self.calibration is not None:
            positions = {s.servo_id: self.calibration.by_id(s.servo_id).neutral_tick for s in self.specs}
        else:
            positions = {s.servo_id: (s.min_position_tick + s.max_position_tick) // 2 for s in self.specs}
        return ChainSpec(
            tuple((s.servo_id, s.model) for s in self.specs),
            baud=config.baud,
            clock=config.clock,
            wire_time=config.wire_time,
            goal_limit=config.goal_limit,
            positions_tick=positions,
        )

    def limits(self, config: ServofaceConfig) -> WireLimits:
        """What goals are checked against: the calibrated limits of a head, else the specs' limits."""
        if self.calibration is not None:
            return WireLimits.from_calibration(self.calibration, rate_hz=config.rate_hz)
        return WireLimits.from_specs(list(self.specs), rate_hz=config.rate_hz)


def load_head_and_calibration(name_or_path: str | Path) -> tuple[Any, Any]:
    """A built-in head name or profile folder -> (Head, the HeadCalibration its profile names)."""
    from servoface.controller.face import head_calibration
    from servoface.sim.heads import load_head

    head = load_head(name_or_path)
    return head, head_calibration(head)


def build_rig(config: ServofaceConfig) -> Rig:
    """The rig a config describes: a head's servos (limits from its calibration, with the driver's margin),
    or the explicit list with ``limits_tick``."""
    from servoface.hardware.servo_config import ServoSpec

    if config.head is not None:
        from servoface.controller.head_servos import servo_specs

        head, cal = load_head_and_calibration(config.head)
        return Rig(tuple(servo_specs(head, cal)), head, cal)
    lo, hi = config.limits_tick
    specs = tuple(
        ServoSpec(sid, model, role=f"servo_{sid}", min_position_tick=lo, max_position_tick=hi)
        for sid, model in config.servo_list()
    )
    return Rig(specs)
