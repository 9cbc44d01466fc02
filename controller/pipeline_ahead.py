"""The next frame, computed while this frame's replies are on the wire (`Pipeline.step(..., next_frame=)`).

While the driver waits for frame N's Present Position replies (`Driver.cycle_start` .. `cycle_finish`), the
pipeline runs frame N+1's muscle model, calibration and a **speculative** gate check: against the command
just sent (N's) and the health the gate used for N. The gate's step memory is put back at once, so the
gate is never left in a speculative state. At step N+1 the speculation is used only if it is exactly what
a check made then would be: the same AUs, the same last command (the driver re-pinned / eased nothing),
the same health (no new telemetry changed it) and the gate's step memory untouched since (no hold/reset).
Otherwise the gate checks afresh. So every command is still checked against the last command actually
sent, with the health of the last cycle; the overlap only moves *when* the same computation runs.

The elapsed time: the gate's rate caps grow with the time since the last command went on the wire
(`servoface.sim.gate.limits.per_time`: the step cap ``floor(cap * f)``, the speed-up cap ``floor(cap * f²)``
and the previous step taken over ``min(1, f / f_last)`` of its time, ``f = min(1, elapsed / period)``, each
non-decreasing in the elapsed time), and every rate check is an interval test that only widens as they grow.
So a **clean accept** (no finding but health: every rate check passed, no state check fired) checked for a
planned elapsed time is also what a check after any *longer* time gives — the same kind, goals and findings
(`Speculation.holds_for`); the pipeline plans a time it is likely to exceed (`Pipeline._plans_s`). Any
other verdict (a clip, or an accept at the limits of a derated servo, whose findings hold a rate check) is
used only when the real time gives exactly the caps it was checked with (`TwinGate.rate_key`): for a frame
that does not accept at the short plan, a second check is made for a later time that the step may wait
for (`Pipeline._reach_plan`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from servoface.sim.gate import ServoHealth, Verdict
from servoface.sim.gate.gate import GateMemory


@dataclass(frozen=True)
class Speculation:
    """One speculative gate check of the next frame, for one planned elapsed time."""

    verdict: Verdict
    rate_key: bytes  # `TwinGate.rate_key` of the check: its caps, step origin and previous step
    plan_s: float | None  # the elapsed time the check assumed (None: a whole period, per-frame caps)

    def holds_for(self, elapsed_s: float | None) -> bool:
        """True if the verdict is a clean accept checked for a planned elapsed time that ``elapsed_s`` (the
        step's, with the inputs `Ahead.matches` compared) reaches: then a check after ``elapsed_s`` gives the
        same verdict (see the module docstring). Else the caller compares rate keys."""
        v, plan_s = self.verdict, self.plan_s
        if v.kind != "accept" or plan_s is None or elapsed_s is None or elapsed_s < plan_s:
            return False
        return all(f.check == "health" for f in v.findings)

    def clean_accept(self) -> bool:
        """A clean accept: good for any elapsed time from its plan on (`holds_for`)."""
        return self.plan_s is not None and self.holds_for(self.plan_s)


@dataclass(frozen=True)
class Ahead:
    """Frame N+1 as computed during frame N's wait."""

    aus: dict[str, float]
    targets: dict[str, float]
    clamped: dict[str, float]
    clamp_reasons: tuple[str, ...]
    requested: dict[int, int]
    timings_ms: dict[str, float]  # muscle_ms, calibration_ms, gate_ms (as spent during the wait)
    last_goals_tick: dict[int, int]
    health: dict[int, ServoHealth] | None
    state_before: GateMemory | None  # the gate's memory the checks started from (None: no check ran)
    speculations: tuple[Speculation, ...] = ()  # in the order of their plans (empty: the step checks)

    def matches(
        self, last_goals_tick: Mapping[int, int], health: Mapping[int, ServoHealth] | None, state: GateMemory
    ) -> bool:
        """True if the speculations' inputs but the elapsed time are exactly the step's (the caller picks a
        speculation by the elapsed time: `Speculation.holds_for`, `TwinGate.rate_key`)."""
        if not self.speculations or self.state_before is None or dict(last_goals_tick) != self.last_goals_tick:
            return False
        if (None if health is None else dict(health)) != self.health:
            return False
        return state.same(self.state_before)
