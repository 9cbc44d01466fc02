"""One servo's calibration: its curve plus tick and target limits, neutral, and optional coupling.

``to_tick`` rounds to the nearest integer tick and refuses non-finite or out-of-range targets with a
:class:`TargetOutOfRangeError` naming the role. Target limits default to the inverse of the tick limits;
they may be given explicitly (the head's actuator range), and must then round into the tick limits.
Accepted targets are the target limits widened by the slack of rounding: every target whose tick rounds
inside the tick limits (``accept_min_target``..``accept_max_target``, less than a tick's worth wider).
So every tick inside the limits maps to an accepted target, and goal -> target -> goal is the identity.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from servoface.calibration.curves import Curve
from servoface.calibration.errors import (
    CalibrationError,
    CurveError,
    TargetOutOfRangeError,
    TickOutOfRangeError,
)
from servoface.calibration.rbf import RbfMap

Unit = Literal["deg", "mm"]
UNITS: tuple[str, ...] = ("deg", "mm")
MIN_POSITION_TICK = 0
MAX_POSITION_TICK = 4095  # position control mode, every supported model (XL330/XL430/XM430/MX-28 2.0)
MAX_SERVO_ID = 252


def round_ticks(ticks: NDArray[np.float64]) -> NDArray[np.int64]:
    """Round half away from zero (ticks are >= 0 here, so half up)."""
    return np.floor(ticks + 0.5).astype(np.int64)


@dataclass(frozen=True, eq=False)
class RbfCoupling:
    """The pull of a skin anchor as a function of its own tick and its neighbours' ticks.

    ``map`` has inputs (own tick, ticks of ``neighbours`` in order) and outputs the target (mm).
    """

    neighbours: tuple[str, ...]
    map: RbfMap

    def __post_init__(self) -> None:
        if self.map.dims != 1 + len(self.neighbours):
            raise CurveError(
                f"coupling: the map takes {self.map.dims} inputs but there are {len(self.neighbours)} "
                "neighbours; expected 1 + number of neighbours (own tick first)"
            )


@dataclass(frozen=True, eq=False)  # identity equality: curves and arrays have no useful ==
class ServoCalibration:
    """Calibration of one servo: actuator target (deg or mm) <-> goal tick."""

    role: str
    servo_id: int
    model: str
    curve: Curve
    min_tick: int
    max_tick: int
    neutral_tick: int
    unit: Unit
    min_target: float = float("nan")  # nan = derived from the tick limits
    max_target: float = float("nan")
    measured_points: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    coupling: RbfCoupling | None = None
    # accepted targets: the limits widened to every target whose tick rounds inside the tick limits
    accept_min_target: float = field(init=False, repr=False, compare=False, default=float("nan"))
    accept_max_target: float = field(init=False, repr=False, compare=False, default=float("nan"))

    def __post_init__(self) -> None:
        who = f"servo '{self.role}' (id {self.servo_id})"
        if not isinstance(self.role, str) or not self.role:
            raise CalibrationError(f"servo role {self.role!r} must be a non-empty string")
        if not isinstance(self.servo_id, int) or not 0 <= self.servo_id <= MAX_SERVO_ID:
            raise CalibrationError(f"{who}: id must be an integer 0..{MAX_SERVO_ID}")
        if self.unit not in UNITS:
            raise CalibrationError(f"{who}: unit {self.unit!r} must be one of {UNITS}")
        ticks = (self.min_tick, self.neutral_tick, self.max_tick)
        if not all(isinstance(t, int | np.integer) for t in ticks):
            raise CalibrationError(f"{who}: min/neutral/max ticks {ticks} must be integers")
        if not MIN_POSITION_TICK <= self.min_tick < self.max_tick <= MAX_POSITION_TICK:
            raise CalibrationError(
                f"{who}: tick limits {self.min_tick}..{self.max_tick} must satisfy "
                f"{MIN_POSITION_TICK} <= min_tick < max_tick <= {MAX_POSITION_TICK}"
            )
        if not self.min_tick <= self.neutral_tick <= self.max_tick:
            raise CalibrationError(
                f"{who}: neutral tick {self.neutral_tick} is outside the limits {self.min_tick}..{self.max_tick}"
            )
        ends = np.sort(self.curve.inverse(np.array([self.min_tick, self.max_tick], dtype=np.float64)))
        lo, hi = self.min_target, self.max_target
        if np.isnan(lo) and np.isnan(hi):
            lo, hi = float(ends[0]), float(ends[1])
        elif np.isnan(lo) or np.isnan(hi) or not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise CalibrationError(f"{who}: target limits {lo!r}..{hi!r} must be finite with min < max")
        else:
            at = self.curve.forward(np.array([lo, hi]))
            if np.any(at < self.min_tick - 0.5 - 1e-6) or np.any(at > self.max_tick + 0.5 + 1e-6):
                raise CalibrationError(
                    f"{who}: target limits {lo:g}..{hi:g} {self.unit} map to ticks "
                    f"{[round(float(a), 2) for a in at]}, which do not round into the tick limits "
                    f"{self.min_tick}..{self.max_tick}"
                )
        object.__setattr__(self, "min_target", float(lo))
        object.__setattr__(self, "max_target", float(hi))
        slack = np.sort(self.curve.inverse(np.array([self.min_tick - 0.5, self.max_tick + 0.5])))
        object.__setattr__(self, "accept_min_target", min(float(lo), float(slack[0])))
        object.__setattr__(self, "accept_max_target", max(float(hi), float(slack[1])))
        object.__setattr__(self, "measured_points", np.asarray(self.measured_points, dtype=np.float64))

    # ---- scalar ---------------------------------------------------------------------------------------
    @property
    def neutral_target(self) -> float:
        """The target at the neutral tick."""
        return float(self.curve.inverse(float(self.neutral_tick)))

    @property
    def direction(self) -> int:
        """+1 when the tick grows with the target, -1 for a reversed servo."""
        return 1 if self.curve.increasing else -1

    def to_tick(self, target: float) -> int:
        """Goal tick for an actuator target; raises TargetOutOfRangeError (naming the role) if refused."""
        return int(self.to_ticks(np.array([target], dtype=np.float64))[0])

    def to_target(self, tick: float, *, clip: bool = False) -> float:
        """Actuator target for a tick in [min_tick, max_tick] (or clipped into it when ``clip``)."""
        return float(self.to_targets(np.array([tick], dtype=np.float64), clip=clip)[0])

    # ---- vectorised -------------------------------------------------------------------------------------
    def check_targets(self, targets: ArrayLike) -> NDArray[np.float64]:
        """Targets as a float array; raises TargetOutOfRangeError for the first non-finite or out-of-range."""
        t = np.asarray(targets, dtype=np.float64)
        bad = ~(np.isfinite(t) & (t >= self.accept_min_target) & (t <= self.accept_max_target))
        if np.any(bad):
            value = float(t[np.unravel_index(int(np.argmax(bad)), t.shape)])
            raise TargetOutOfRangeError(self.role, value, self.min_target, self.max_target, self.unit)
        return t

    def to_ticks(self, targets: ArrayLike) -> NDArray[np.int64]:
        """Goal ticks (int64, same shape) for targets; all-or-nothing: one bad target refuses the batch."""
        t = self.check_targets(targets)
        ticks = round_ticks(self.curve.forward(t))
        return np.clip(ticks, self.min_tick, self.max_tick)

    def to_targets(self, ticks: ArrayLike, *, clip: bool = False) -> NDArray[np.float64]:
        """Targets (float, same shape) for ticks; refuses non-finite and (unless ``clip``) out-of-limit
        ticks."""
        k = np.asarray(ticks, dtype=np.float64)
        if not np.all(np.isfinite(k)):
            value = float(k[np.unravel_index(int(np.argmax(~np.isfinite(k))), k.shape)])
            raise TickOutOfRangeError(self.role, value, self.min_tick, self.max_tick)
        if clip:
            k = np.clip(k, self.min_tick, self.max_tick)
        else:
            bad = (k < self.min_tick) | (k > self.max_tick)
            if np.any(bad):
                value = float(k[np.unravel_index(int(np.argmax(bad)), k.shape)])
                raise TickOutOfRangeError(self.role, value, self.min_tick, self.max_tick)
        return self.curve.inverse(k)

    def target_resolution(self) -> float:
        """The largest target step one tick can make anywhere in the limits (deg or mm per tick)."""
        t = np.linspace(self.min_target, self.max_target, 257)
        return float(1.0 / np.min(np.abs(self.curve.slope(t))))

    def position_limits_tick(self, margin_tick: int = 0) -> tuple[int, int]:
        """(Min Position Limit, Max Position Limit) to write to EEPROM (regs 52 / 48) as a backstop.

        ``margin_tick`` widens the window so the servo-side limit never fights a legal goal.
        """
        if margin_tick < 0:
            raise CalibrationError(f"servo '{self.role}': margin {margin_tick} tick must be >= 0")
        return (
            max(MIN_POSITION_TICK, self.min_tick - margin_tick),
            min(MAX_POSITION_TICK, self.max_tick + margin_tick),
        )
