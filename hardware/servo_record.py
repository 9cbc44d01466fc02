"""The driver's mutable record of one servo (private to the bus thread); frozen into `ServoState`.

`ServoRecord.freeze` runs for every servo every cycle. Between telemetry reads only the position, its time,
the goal and the stale flag change, so the last `ServoState` is kept with a key of everything else it is
made from: while that key is unchanged, the new state is the last one's fields with those four replaced
(~0.5 us instead of ~3 us for the dataclass ``__init__``); otherwise it is built afresh (`freeze_full`).
Both give equal states (tests/hardware/test_record_freeze.py mutates every field of the record).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field

from servoface.hardware.fault_policy import ThermalTrend
from servoface.hardware.registers import VELOCITY_RPM_PER_LSB, HardwareErrorBits, ModelInfo, Register
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.snapshot import FaultKind, ServoState, StateCapture

_NO_FAULTS: frozenset[FaultKind] = frozenset()


@dataclass
class ServoRecord:
    spec: ServoSpec
    info: ModelInfo
    thermal: ThermalTrend
    temperature_limit_c: int
    current_limit: int | None = None
    position_tick: int | None = None
    position_t_s: float | None = None
    goal_tick: int | None = None
    velocity_raw: int | None = None
    current_raw: int | None = None
    moving: bool | None = None
    temperature_c: int | None = None
    voltage_v: float | None = None
    telemetry_t_s: float | None = None
    hardware_error: HardwareErrorBits = HardwareErrorBits.NONE
    torque_wanted: bool = False  # what the user asked for
    torque_on: bool = False  # what the driver believes the servo has
    missing: bool = False
    stale: bool = False
    failures: int = 0
    last_probe_s: float = float("-inf")
    faults: set[FaultKind] = field(default_factory=set)
    derated: bool = False
    backoff_scale: float = 1.0  # load back-off: share of (goal - present) still allowed
    seconds_to_limit: float | None = None
    voltage_count: int = 0  # consecutive out-of-range readings (signed: -n low, +n high)
    reboot_at_s: float | None = None  # reboot scheduled (after cool-down)
    reboot_reason: FaultKind | None = None
    fault_t_s: float = float("-inf")  # when the fault behind the scheduled reboot was seen
    recover_at_s: float | None = None  # re-configure + re-pin after a reboot settles
    reboots: deque[float] = field(default_factory=lambda: deque(maxlen=16))
    latched: bool = False
    _frozen: ServoState | None = field(default=None, repr=False, compare=False)  # the last freeze()
    _frozen_key: tuple[object, ...] | None = field(default=None, repr=False, compare=False)

    @property
    def servo_id(self) -> int:
        return self.spec.servo_id

    @property
    def limits_tick(self) -> tuple[int, int]:
        return self.spec.min_position_tick, self.spec.max_position_tick

    @property
    def in_service(self) -> bool:
        """Goals are written only to servos that are present, powered, and not held off by the policy."""
        return (
            not self.missing
            and self.torque_on
            and not self.latched
            and self.reboot_at_s is None
            and self.recover_at_s is None
        )

    @property
    def load_fraction(self) -> float | None:
        if self.current_raw is None:
            return None
        if self.info.reports_current:
            limit = self.current_limit or 0
            return self.current_raw / limit if limit > 0 else None
        return self.current_raw / 1000.0

    def clamp(self, tick: int) -> int:
        lo, hi = self.limits_tick
        return max(lo, min(hi, tick))

    def apply_motion(self, values: Mapping[Register, int], t_s: float) -> None:
        self.moving = bool(values[Register.MOVING])
        self.current_raw = values[Register.PRESENT_CURRENT]
        self.velocity_raw = values[Register.PRESENT_VELOCITY]

    def _slow_key(self) -> tuple[object, ...]:
        """Everything a `ServoState` is made of except position, its time, goal and stale."""
        return (
            self.spec,
            self.info,
            self.current_limit,
            self.velocity_raw,
            self.current_raw,
            self.moving,
            self.temperature_c,
            self.voltage_v,
            self.telemetry_t_s,
            self.hardware_error,
            self.torque_on,
            self.missing,
            self.derated,
            frozenset(self.faults) if self.faults else _NO_FAULTS,
            self.seconds_to_limit,
        )

    def freeze(self) -> ServoState:
        """The record as a `ServoState` (equal to `freeze_full`; cheap while only the position moved)."""
        key = self._slow_key()
        last = self._frozen
        if last is None or key != self._frozen_key:
            last = self.freeze_full()
            self._frozen, self._frozen_key = last, key
            return last
        was = last.__dict__
        if (
            was["position_tick"] == self.position_tick
            and was["position_t_s"] == self.position_t_s
            and was["goal_tick"] == self.goal_tick
            and was["stale"] == self.stale
        ):
            return last  # frozen: safe to share between snapshots
        fields = was.copy()
        fields["position_tick"] = self.position_tick
        fields["position_t_s"] = self.position_t_s
        fields["goal_tick"] = self.goal_tick
        fields["stale"] = self.stale
        state: ServoState = object.__new__(ServoState)
        object.__setattr__(state, "__dict__", fields)  # a frozen dataclass: its fields, bypassing __init__
        self._frozen = state
        return state

    def freeze_lazy(self) -> ServoState | StateCapture:
        """`freeze`, except that a state which would be the last one with only position, its time, goal and
        stale replaced is returned as a capture of those values (`build_state` makes the equal state)."""
        key = self._slow_key()
        last = self._frozen
        if last is None or key != self._frozen_key:
            last = self.freeze_full()
            self._frozen, self._frozen_key = last, key
            return last
        was = last.__dict__
        position_tick, position_t_s, goal_tick, stale = (
            self.position_tick,
            self.position_t_s,
            self.goal_tick,
            self.stale,
        )
        if (
            was["position_tick"] == position_tick
            and was["position_t_s"] == position_t_s
            and was["goal_tick"] == goal_tick
            and was["stale"] == stale
        ):
            return last  # frozen: safe to share between snapshots
        return (last, position_tick, position_t_s, goal_tick, stale)

    def calm_base(self, now_s: float) -> ServoState | None:
        """The state a capture would start from if, before the next freeze at ``now_s``, only the position,
        its time, goal and stale change (a calm cycle, `calm_cycle`): the last state while the slow key is
        unchanged and its position time is not ``now_s`` (so `freeze_lazy` would capture, not share it);
        else None. Checked while the position replies are on the wire, so the freeze after them is a
        capture per servo with no key to build."""
        last = self._frozen
        if last is None or last.__dict__["position_t_s"] == now_s or self._slow_key() != self._frozen_key:
            return None
        return last

    def freeze_full(self) -> ServoState:
        """The record as a `ServoState`, built field by field (the reference for `freeze`)."""
        current_ma = (
            self.current_raw * self.info.current_ma_per_lsb
            if self.current_raw is not None and self.info.reports_current
            else None
        )
        return ServoState(
            servo_id=self.servo_id,
            position_tick=self.position_tick,
            goal_tick=self.goal_tick,
            velocity_rpm=None if self.velocity_raw is None else self.velocity_raw * VELOCITY_RPM_PER_LSB,
            current_ma=current_ma,
            load_fraction=self.load_fraction,
            temperature_c=self.temperature_c,
            voltage_v=self.voltage_v,
            hardware_error=self.hardware_error,
            moving=self.moving,
            torque_on=self.torque_on,
            missing=self.missing,
            stale=self.stale,
            derated=self.derated,
            faults=frozenset(self.faults) if self.faults else _NO_FAULTS,
            position_t_s=self.position_t_s,
            telemetry_t_s=self.telemetry_t_s,
            seconds_to_temperature_limit=self.seconds_to_limit,
        )
