"""What the wire assertions check goals against: per servo its role, calibrated (or configured) limits and
the gate's per-frame speed and acceleration caps (`servoface.sim.gate.limits`, the same numbers the twin
gate enforces)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from servoface.calibration import HeadCalibration
from servoface.hardware.servo_config import ServoSpec
from servoface.sim.gate import GateConfig
from servoface.sim.gate import limits as lim
from servoface.testing.errors import TestKitConfigError

DEFAULT_RATE_HZ = 50.0


@dataclass(frozen=True)
class ServoLimit:
    servo_id: int
    role: str
    model: str
    min_tick: int
    max_tick: int

    @property
    def label(self) -> str:
        return f"servo {self.servo_id}" + (f" '{self.role}'" if self.role else "")


@dataclass(frozen=True)
class WireLimits:
    """Limits per servo id, plus ``table``: the gate's `ServoTable` (per-frame caps at ``rate_hz``) over the
    servos whose model has a known speed (``uncapped`` lists the others)."""

    servos: dict[int, ServoLimit]
    rate_hz: float
    table: lim.ServoTable | None
    uncapped: tuple[int, ...]
    source: str

    def label(self, servo_id: int) -> str:
        s = self.servos.get(servo_id)
        return s.label if s is not None else f"servo {servo_id}"

    @classmethod
    def build(
        cls,
        servos: Iterable[ServoLimit],
        *,
        rate_hz: float = DEFAULT_RATE_HZ,
        gate: GateConfig | None = None,
        source: str,
    ) -> WireLimits:
        if not (isinstance(rate_hz, int | float) and 0 < rate_hz < float("inf")):
            raise TestKitConfigError(f"wire limits: rate_hz {rate_hz!r}; expected a positive number of frames/s")
        cfg = gate or GateConfig()
        by_id = {s.servo_id: s for s in servos}
        capped = [s for s in by_id.values() if s.model in lim.NO_LOAD_SPEED_RPM]
        table = None
        if capped:
            step, speedup = lim.rate_caps_tick(
                [s.model for s in capped], 1.0 / float(rate_hz), cfg.speed_share, cfg.accel_time_s
            )
            for i, s in enumerate(capped):
                step[i] = int(cfg.max_step_tick.get(s.role, step[i]))
                speedup[i] = int(cfg.max_speedup_tick.get(s.role, speedup[i]))
            lo = np.array([s.min_tick for s in capped], dtype=np.int64)
            hi = np.array([s.max_tick for s in capped], dtype=np.int64)
            table = lim.ServoTable(
                tuple(s.servo_id for s in capped), tuple(s.role for s in capped), lo, hi, (lo + hi) // 2, step, speedup
            )
        uncapped = tuple(sorted(sid for sid, s in by_id.items() if s.model not in lim.NO_LOAD_SPEED_RPM))
        return cls(by_id, float(rate_hz), table, uncapped, source)

    @classmethod
    def from_calibration(
        cls, calibration: HeadCalibration, *, rate_hz: float = DEFAULT_RATE_HZ, gate: GateConfig | None = None
    ) -> WireLimits:
        """The calibrated limits (the twin gate's, not the servo-side backstop's wider ones)."""
        servos = [ServoLimit(s.servo_id, s.role, s.model, s.min_tick, s.max_tick) for s in calibration.servos]
        return cls.build(servos, rate_hz=rate_hz, gate=gate, source="calibration")

    @classmethod
    def from_specs(
        cls, specs: Sequence[ServoSpec], *, rate_hz: float = DEFAULT_RATE_HZ, gate: GateConfig | None = None
    ) -> WireLimits:
        """The configured limits of servo descriptions (Min/Max Position Limit as the driver writes them)."""
        servos = [ServoLimit(s.servo_id, s.role, s.model, s.min_position_tick, s.max_position_tick) for s in specs]
        return cls.build(servos, rate_hz=rate_hz, gate=gate, source="servo specs")

    def caps(self, servo_id: int) -> tuple[int, int] | None:
        """(max_step_tick, max_speedup_tick) per frame, or None when the model's speed is unknown."""
        if self.table is None or servo_id not in self.table.ids:
            return None
        i = self.table.ids.index(servo_id)
        return int(self.table.max_step_tick[i]), int(self.table.max_speedup_tick[i])
