"""The jaw's duty cycle on a talking head: a thermal budget for long speech, in step with the driver.

Why: the jaw works hardest of all the servos on a talking head (an InMoov builder burned a dozen jaw
servos). The driver's thermal policy (``hardware/fault_policy.py``) reacts only once the servo is already
hot: it derates at (limit - ``thermal_margin_c``) or when the limit is predicted within 120 s, and switches
torque off at (limit - ``thermal_off_margin_c``). The speech planner keeps the jaw from getting there:

- **duty**: the jaw's planned opening ``d(t)`` (the plan's ``open`` feature, 0..1) is the share of its load
  the servo carries (holding the jaw open against its spring and gravity, moving it);
- **account**: a servo heats as ``T' = (T_ambient + rise * load**2 - T) / tau`` (the emulator's model,
  ``hardware/emulator/physics.py``, and the first-order law of a DC motor's winding), so the budget keeps
  ``u``, the jaw's ``d**2`` through the same first-order filter (``window_s`` = 60 s, the servos' thermal
  time constant), carried from one utterance to the next (it decays while the head is silent): ``u`` is the
  share of its full steady-state heating that speech costs the jaw;
- **budget**: ``u <= max_duty`` (0.06). Conversational espeak speech has a mean ``d**2`` of about 0.09, so
  a head may talk without a pause for about a minute, or half of the time for ever, before the budget
  bites; from 70 % of the budget the jaw opening is scaled down (to half at the budget, so a long talk
  settles on a uniformly smaller jaw, not on clipped peaks) and a hard guard keeps ``u`` within the
  budget (attack at once, recovery at ``recover_per_s``): every viseme is still shaped by the lips and
  the bilabials still close; only the jaw opens less, like a speaker talking through their teeth;
- **the driver's state** sets the budget: below (limit - margin - ``taper_c``) the full budget; from there
  to the derate threshold the budget falls to a quarter; when the driver's :func:`thermal_level` is 1
  (derating) the jaw opens at most half as far on a quarter budget; at level 2 (torque off) speech does
  not drive the jaw at all (lips only). The same ``FaultPolicy`` numbers decide both.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.plan import LipSyncPlan
from servoface.controller.speech.visemes import FEATURES
from servoface.hardware.fault_policy import FaultPolicy, thermal_level

DEFAULT_WINDOW_S = 60.0
DEFAULT_MAX_DUTY = 0.06
DEFAULT_TAPER_C = 10.0
DEFAULT_RECOVER_PER_S = 0.5
KNEE = 0.7  # the jaw starts opening less when the account passes this share of the budget ...
MIN_SCALE = 0.5  # ... down to this scale at the budget (beyond it, a hard guard keeps the account within)


@dataclass(frozen=True)
class JawThermal:
    """The jaw servo as the driver last saw it."""

    temperature_c: float
    limit_c: float
    seconds_to_limit_s: float | None = None


@dataclass(frozen=True)
class BudgetReport:
    """What the budget did to one utterance."""

    budget: float  # the cap on the account for this utterance
    jaw_gain: float  # the thermal gain on the jaw's opening (1 = full)
    level: int  # the driver's thermal level of the jaw (0 fine, 1 derate, 2 torque off; 0 without a reading)
    account_before: float
    account_after: float
    peak_account: float
    min_scale: float  # the smallest scale the budget put on the jaw's opening (1 = untouched)
    scaled_share: float  # the share of the utterance's samples whose jaw opening was scaled down


class JawBudget:
    """One head's jaw account (keep one per head, across utterances)."""

    def __init__(
        self,
        *,
        window_s: float = DEFAULT_WINDOW_S,
        max_duty: float = DEFAULT_MAX_DUTY,
        taper_c: float = DEFAULT_TAPER_C,
        recover_per_s: float = DEFAULT_RECOVER_PER_S,
        policy: FaultPolicy | None = None,
    ) -> None:
        for name, value, lo, hi in (
            ("window_s", window_s, 1.0, 3600.0),
            ("max_duty", max_duty, 0.0, 1.0),
            ("taper_c", taper_c, 0.0, 50.0),
            ("recover_per_s", recover_per_s, 0.01, 100.0),
        ):
            if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
                raise SpeechError(f"jaw budget: {name} must be a number within {lo:g}..{hi:g}, got {value!r}")
        self.window_s = float(window_s)
        self.max_duty = float(max_duty)
        self.taper_c = float(taper_c)
        self.recover_per_s = float(recover_per_s)
        self.policy = policy or FaultPolicy()
        self.account = 0.0
        self._t_s: float | None = None  # when the account was last brought up to date (monotonic)

    def account_at(self, t_s: float) -> float:
        """The account at ``t_s`` (it decays while the jaw rests)."""
        if self._t_s is None or t_s <= self._t_s:
            return self.account
        return self.account * math.exp(-(t_s - self._t_s) / self.window_s)

    def limits(self, jaw: JawThermal | None) -> tuple[float, float, int]:
        """(budget, jaw gain, thermal level) for the jaw's state (None: no reading, the full budget)."""
        if jaw is None:
            return self.max_duty, 1.0, 0
        p = self.policy
        level = thermal_level(jaw.temperature_c, jaw.limit_c, jaw.seconds_to_limit_s, p)
        if level >= 2:
            return 0.0, 0.0, level
        if level == 1:
            return self.max_duty * 0.25, 0.5, level
        derate_at = jaw.limit_c - p.thermal_margin_c
        headroom = (derate_at - jaw.temperature_c) / self.taper_c if self.taper_c > 0 else 1.0
        share = 0.25 + 0.75 * min(1.0, max(0.0, headroom))
        return self.max_duty * share, 1.0, level

    @staticmethod
    def _soft_scale(u: float, budget: float) -> float:
        """The jaw's scale from how full the account is: 1 below ``KNEE`` of the budget, down to ``MIN_SCALE``
        at the budget (so a long talk settles on a uniformly smaller jaw, not on clipped peaks)."""
        if budget <= 0:
            return 0.0
        full = (u - KNEE * budget) / ((1.0 - KNEE) * budget)
        return 1.0 - (1.0 - MIN_SCALE) * min(1.0, max(0.0, full))

    def apply(
        self, plan: LipSyncPlan, start_s: float, jaw: JawThermal | None = None
    ) -> tuple[LipSyncPlan, BudgetReport]:
        """The plan with its jaw opening within the budget, starting at ``start_s`` (monotonic); the
        account then runs to the plan's end."""
        j = FEATURES.index("open")
        opening, report = self.apply_opening(plan.times_s, plan.features[:, j], start_s, jaw)
        features = np.array(plan.features, dtype=float, copy=True)
        features[:, j] = opening
        return dataclasses.replace(plan, features=features), report

    def apply_opening(
        self, times_s: NDArray[np.float64], opening: NDArray[np.float64], start_s: float, jaw: JawThermal | None = None
    ) -> tuple[NDArray[np.float64], BudgetReport]:
        """The jaw's opening (0..1 at ``times_s``, mouth clock from ``start_s`` monotonic) within the budget:
        what :meth:`apply` does to a plan, for any mouth (a script's edited keys too); the account then
        runs to the last time."""
        budget, gain, level = self.limits(jaw)
        t = np.asarray(times_s, dtype=float)
        wanted = np.clip(np.asarray(opening, dtype=float), 0.0, None) * gain
        u = before = self.account_at(start_s)
        out = np.empty_like(wanted)
        scale, peak, min_scale, scaled = 1.0, u, 1.0, 0
        prev_t = float(t[0]) if len(t) else 0.0
        for i, (ti, d) in enumerate(zip(t.tolist(), wanted.tolist(), strict=True)):
            dt = max(ti - prev_t, 1e-6) if i else 1.0 / 100.0
            prev_t = ti
            a = 1.0 - math.exp(-dt / self.window_s)
            allowed_sq = u + (budget - u) / a  # the largest d**2 that keeps the account within the budget
            allowed = math.sqrt(allowed_sq) if allowed_sq > 0 else 0.0
            hard = 1.0 if d <= allowed or d <= 0 else allowed / d
            want = min(hard, self._soft_scale(u, budget))
            scale = want if want < scale else min(want, scale + self.recover_per_s * dt)
            d_eff = d * scale
            if scale < 1.0 - 1e-9:
                scaled += 1
            min_scale = min(min_scale, scale)
            u += (d_eff * d_eff - u) * a
            peak = max(peak, u)
            out[i] = d_eff
        self.account = u
        self._t_s = start_s + (float(t[-1]) if len(t) else 0.0)
        report = BudgetReport(budget, gain, level, before, u, peak, min_scale, scaled / len(t) if len(t) else 0.0)
        return out, report


def jaw_thermal(service: object, jaw_id: int) -> JawThermal | None:
    """The jaw servo's last temperature reading from a head service's driver (None: offline or unread)."""
    snap = getattr(service, "telemetry", lambda: None)()
    driver = getattr(service, "driver", None)
    if snap is None or driver is None or jaw_id not in snap.servos:
        return None
    state = snap.servos[jaw_id]
    if state.temperature_c is None:
        return None
    limit = driver.temperature_limit_c(jaw_id)
    return JawThermal(float(state.temperature_c), float(limit), state.seconds_to_temperature_limit)
