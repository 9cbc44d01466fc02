"""The optional non-ideal servo (``ServoChain.create(..., realism=...)``, off by default).

An ideal emulated servo lands exactly on its goal. A real one does not, and code (or a fidelity figure)
that only passes on ideal servos fails on the bench. With realism on, each servo's physical output differs
from the ideal profile by:

- **lag**: the output follows the ideal position through a first-order lag whose time constant grows with
  load (``lag_s`` · (1 + |load|·``lag_load_gain``)), so it trails a moving goal in proportion to speed;
- **load error**: a proportional position loop (the default Position I Gain is 0) needs an error to make
  torque: ``load_error_tick`` per unit of load (fraction of stall), trailing the motion; at rest the holding
  load pulls it short on the side it approached from;
- **backlash**: the gear train's play, ``backlash_tick`` wide; the output only moves once the play is taken
  up, so a reversal leaves it short by up to the play;
- **encoder noise**: each Present Position read is off by a random integer in ±``encoder_noise_tick``;
- **temperature-dependent current**: the current (and load estimate) for the same torque rises by
  ``current_tempco_per_c`` per degree above 25 °C (the motor's torque constant falls as its magnet warms).

Default magnitudes (XL330/XL430 class; the pages give no backlash or noise for these models, so these are
the nearest published figures, documented in the README's emulator section):

- backlash 3.8 ticks: 0.33° (20 arcmin), the backlash ROBOTIS states for the MX-28(2.0) (e-manual
  specification table); plastic-geared XL330s are not tighter;
- encoder noise ±1 tick: one LSB of the 12-bit AS5601 encoder the XL330 page names;
- load error 64 ticks at stall: the emulator's own position-loop stiffness (``physics.STALL_FULL_ERROR_TICK``)
  so the error and the reported current agree; holding (3 % of stall) is ~2 ticks;
- lag 15 ms: the settling time-constant of the default position P gain (400/128 per the e-manual's
  controller diagram) acting on the XL330's 0.229 rpm velocity unit, about 10-20 ms;
- current tempco 0.2 %/°C: the remanence tempco of ferrite magnets (-0.2 %/°C), the cored motors' type.

All randomness comes from one seeded generator per servo, so a run is reproducible.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field, replace
from typing import Any

from servoface.hardware.emulator.errors import EmulatorConfigError

HOLD_LOAD = 0.03  # fraction of stall drawn while holding (physics.HOLD_LOAD)


@dataclass(frozen=True)
class Realism:
    """Magnitudes of the non-ideal servo model (see the module docstring for their sources)."""

    backlash_tick: float = 3.8
    encoder_noise_tick: int = 1
    load_error_tick: float = 64.0
    lag_s: float = 0.015
    lag_load_gain: float = 2.0
    current_tempco_per_c: float = 0.002
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("backlash_tick", "load_error_tick", "lag_s", "lag_load_gain", "current_tempco_per_c"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                raise EmulatorConfigError(f"realism {name} {value!r}: expected a finite number >= 0")
        if not isinstance(self.encoder_noise_tick, int) or self.encoder_noise_tick < 0:
            raise EmulatorConfigError(f"realism encoder_noise_tick {self.encoder_noise_tick!r}: expected an int >= 0")

    @classmethod
    def coerce(cls, value: Realism | bool | dict[str, Any] | None) -> Realism | None:
        """None/False (off), True (defaults), a dict of field overrides, or a Realism."""
        if value is None or value is False:
            return None
        if value is True:
            return cls()
        if isinstance(value, Realism):
            return value
        if isinstance(value, dict):
            unknown = set(value) - set(cls.__dataclass_fields__)
            if unknown:
                raise EmulatorConfigError(
                    f"realism: unknown field(s) {sorted(unknown)}; expected some of {sorted(cls.__dataclass_fields__)}"
                )
            return replace(cls(), **value)
        raise EmulatorConfigError(f"realism {value!r}: expected None, True/False, a dict or a Realism")


@dataclass
class RealState:
    """One servo's physical output under ``Realism`` (raw ticks, like ``MotorState.pos``)."""

    spec: Realism
    rng: random.Random
    lagged: float  # the position loop's lagged follow of the ideal position
    output: float  # the output shaft after the gear play
    direction: float = 1.0  # the last direction of motion (+1 / -1)
    pos: float = field(init=False)

    def __post_init__(self) -> None:
        self.pos = self.output

    @classmethod
    def create(cls, spec: Realism, servo_id: int, pos_tick: float) -> RealState:
        return cls(spec, random.Random(spec.seed * 1_000_003 + servo_id), pos_tick, pos_tick)

    def reset(self, pos_tick: float) -> None:
        """The shaft was put at ``pos_tick`` (by hand, or at power-up): no lag, the play centred."""
        self.lagged = self.output = self.pos = pos_tick

    def update(self, ideal_tick: float, vel_tick_s: float, load: float, dt_s: float) -> None:
        """Move on by ``dt_s`` with the ideal position, velocity and signed load fraction at its end."""
        s = self.spec
        if vel_tick_s > 0:
            self.direction = 1.0
        elif vel_tick_s < 0:
            self.direction = -1.0
        tau = s.lag_s * (1.0 + abs(load) * s.lag_load_gain)
        k = 1.0 if tau <= 0 else 1.0 - math.exp(-dt_s / tau)
        self.lagged += (ideal_tick - self.lagged) * k
        half = s.backlash_tick / 2.0
        if self.lagged - self.output > half:
            self.output = self.lagged - half
        elif self.output - self.lagged > half:
            self.output = self.lagged + half
        moving = vel_tick_s != 0.0
        effort = abs(load) if moving else min(abs(load), HOLD_LOAD)
        self.pos = self.output - self.direction * effort * s.load_error_tick

    def read_tick(self, present_tick: float) -> int:
        """One Present Position reading of the physical ``present_tick`` (with encoder noise)."""
        n = self.spec.encoder_noise_tick
        return round(present_tick) + (self.rng.randint(-n, n) if n else 0)

    def current_scale(self, temperature_c: float) -> float:
        return 1.0 + self.spec.current_tempco_per_c * (temperature_c - 25.0)
