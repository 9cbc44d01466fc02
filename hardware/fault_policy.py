"""Fault policy: thresholds and the pure decisions the driver takes on them (tested without a bus).

The reactions themselves (which register is written when) live in `servoface.hardware.driver`; the table in the
README section "Faults" lists both.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

WATCHDOG_UNIT_S = 0.02  # Bus Watchdog (address 98) counts 20 ms units


@dataclass(frozen=True)
class FaultPolicy:
    """Every threshold of the fault reactions. Times in seconds of the driver clock."""

    retries: int = 1  # extra attempts of a failed group read before per-servo fallback reads
    missing_after_failures: int = 2  # consecutive cycles a servo's own read fails before it is marked missing
    reprobe_interval_s: float = 0.25  # ping each missing servo this often (one ping per cycle at most)
    reconnect_interval_s: float = 0.5  # re-open a failed port this often
    # overload
    load_backoff_fraction: float = 0.8  # |load| above this fraction of the limit: ease goals toward present
    backoff_gain: float = 0.5  # each high-load reading: reach of (goal - present) x gain
    overload_cooldown_s: float = 2.0  # after an overload shutdown: wait, then reboot
    reboot_settle_s: float = 0.1  # a rebooted servo is silent this long
    max_reboots: int = 3  # per servo within reboot_window_s; one more -> latched (torque stays off)
    reboot_window_s: float = 60.0
    reboot_backoff_s: float = 0.25  # a hardware-error reboot waits this, doubled per recent reboot of that servo
    # stopping and host death
    configure_attempts: int = 3  # tries per servo at start-up when a reply is lost or garbled (writes are idempotent)
    torque_off_attempts: int = 3  # Torque Enable = 0 tries per servo when stopping (carrying on past failures)
    watchdog_s: float = 0.1  # Bus Watchdog armed while driving (20 ms units, 0.02..2.54 s); 0 = never armed
    # temperature
    thermal_margin_c: float = 5.0  # derate at (limit - margin) ...
    thermal_derate_horizon_s: float = 120.0  # ... or when predicted to reach the limit within this
    thermal_off_horizon_s: float = 20.0  # torque off when predicted to reach the limit within this
    thermal_off_margin_c: float = 1.0  # ... or at (limit - this)
    thermal_resume_margin_c: float = 10.0  # back in service (and reboot if the servo shut down) below limit - this
    thermal_window_s: float = 30.0  # rate of rise: least-squares slope over this window
    derate_profile_velocity: int = 40  # Profile Velocity while derated (0.229 rpm units)
    # supply voltage (defaults: the model's recommended supply range)
    voltage_low_v: float | None = None
    voltage_high_v: float | None = None
    voltage_debounce: int = 2  # consecutive readings out of range before reacting
    # telemetry rates (Hz): positions every cycle; slow groups round-robin, at most one per cycle
    motion_hz: float = 10.0  # current/load, velocity, moving
    thermal_hz: float = 2.0  # temperature, input voltage
    status_hz: float = 10.0  # torque enable + hardware error status
    # a due group is read when the caller leaves the bus idle at least as long as the group's read takes
    # (a paced loop: nominal rates) and otherwise once this share of its rate is reached (cycles run back to
    # back: the reads would cost the goals' rate). An Alert bit in any reply reads the status group at once.
    telemetry_floor_share: float = 0.25
    # While positions are read through the position sentinel (hardware/sentinel.py; `Driver.sentinel_info`),
    # a reset servo shows in the next plain cycle's position reply (its Indirect Address map gone) and a
    # hardware error in the Alert bit, so back to back the status group (Torque Enable, Hardware Error
    # Status) is read only at least every this many seconds instead of at the floor share of its rate (0.4 s
    # by default). It is kept, not dropped: that a lost map reads 0 after a reset is verified on the
    # emulator only, not on a real servo, and this read is what sees a reset where that is not so. It is
    # still read at its nominal rate when the bus is idle and at once when an Alert bit or a reaction asks.
    sentinel_status_floor_s: float = 2.0

    def __post_init__(self) -> None:
        for name in (
            "retries",
            "configure_attempts",
            "missing_after_failures",
            "max_reboots",
            "voltage_debounce",
            "torque_off_attempts",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < (1 if name != "retries" else 0):
                raise ValueError(f"FaultPolicy.{name} = {value!r}: expected a positive int")
        for name, value in vars(self).items():
            if isinstance(value, float) and (not math.isfinite(value) or value < 0):
                raise ValueError(f"FaultPolicy.{name} = {value!r}: expected a finite value >= 0")
        if not 0 < self.telemetry_floor_share <= 1:
            raise ValueError(
                f"FaultPolicy.telemetry_floor_share = {self.telemetry_floor_share}: expected 0 < share <= 1"
            )
        floor = self.sentinel_status_floor_s
        if isinstance(floor, bool) or not isinstance(floor, int | float) or not 0 < floor < math.inf:
            raise ValueError(f"FaultPolicy.sentinel_status_floor_s = {floor!r}: expected a finite time > 0 s")
        if not 0 <= self.backoff_gain <= 1:
            raise ValueError(f"FaultPolicy.backoff_gain = {self.backoff_gain}: expected 0..1")
        if self.watchdog_s and not WATCHDOG_UNIT_S <= self.watchdog_s <= 127 * WATCHDOG_UNIT_S:
            raise ValueError(
                f"FaultPolicy.watchdog_s = {self.watchdog_s}: expected 0 (off) or "
                f"{WATCHDOG_UNIT_S:g}..{127 * WATCHDOG_UNIT_S:g} s (the register counts 20 ms units)"
            )

    @property
    def watchdog_units(self) -> int:
        """The Bus Watchdog register value (20 ms units, 1..127), or 0 when the watchdog is off."""
        if not self.watchdog_s:
            return 0
        return max(1, min(127, round(self.watchdog_s / WATCHDOG_UNIT_S)))

    def reboot_delay_s(self, recent_reboots: int) -> float:
        """Exponential back-off: how long a hardware-error reboot waits after the fault was seen."""
        return self.reboot_backoff_s * 2.0 ** min(recent_reboots, 16)


def eased_goal(goal_tick: int, present_tick: int, scale: float, min_tick: int, max_tick: int) -> int:
    """A goal moved toward the present position (load back-off), always inside [min_tick, max_tick]."""
    target = present_tick + scale * (goal_tick - present_tick)
    return max(min_tick, min(max_tick, int(round(target))))


class ThermalTrend:
    """Temperature history of one servo; predicts the time to reach its limit from the rate of rise.

    Temperatures are whole degrees, so the slope is a least-squares fit over ``window_s`` (not a
    difference of two readings).
    """

    def __init__(self, window_s: float) -> None:
        self.window_s = window_s
        self._samples: deque[tuple[float, float]] = deque()

    def add(self, t_s: float, temperature_c: float) -> None:
        self._samples.append((t_s, temperature_c))
        while self._samples and self._samples[0][0] < t_s - self.window_s:
            self._samples.popleft()

    def clear(self) -> None:
        self._samples.clear()

    @property
    def slope_c_per_s(self) -> float | None:
        """Least-squares rate of rise; None with fewer than 3 samples or under 2 s of history."""
        if len(self._samples) < 3:
            return None
        t0 = self._samples[0][0]
        ts = [t - t0 for t, _ in self._samples]
        if ts[-1] < 2.0:
            return None
        ys = [y for _, y in self._samples]
        n = len(ts)
        mt, my = sum(ts) / n, sum(ys) / n
        var = sum((t - mt) ** 2 for t in ts)
        if var <= 0:
            return None
        return sum((t - mt) * (y - my) for t, y in zip(ts, ys, strict=True)) / var

    def seconds_to(self, limit_c: float) -> float | None:
        """Predicted seconds until ``limit_c`` at the current rate; 0 at/over it; None if not rising."""
        if not self._samples:
            return None
        latest = self._samples[-1][1]
        if latest >= limit_c:
            return 0.0
        slope = self.slope_c_per_s
        if slope is None or slope <= 1e-4:
            return None
        return (limit_c - latest) / slope


def thermal_level(temperature_c: float, limit_c: float, seconds_to_limit: float | None, policy: FaultPolicy) -> int:
    """0 = fine, 1 = derate, 2 = torque off (before the servo's own shutdown at the limit)."""
    if temperature_c >= limit_c - policy.thermal_off_margin_c or (
        seconds_to_limit is not None and seconds_to_limit <= policy.thermal_off_horizon_s
    ):
        return 2
    if temperature_c >= limit_c - policy.thermal_margin_c or (
        seconds_to_limit is not None and seconds_to_limit <= policy.thermal_derate_horizon_s
    ):
        return 1
    return 0


def voltage_state(voltage_v: float, low_v: float, high_v: float) -> int:
    """-1 below ``low_v``, +1 above ``high_v``, 0 within."""
    if voltage_v < low_v:
        return -1
    if voltage_v > high_v:
        return 1
    return 0
