"""The next frame, computed while this frame's replies are on the wire (`Pipeline.step(..., next_frame=)`).

While the driver waits for frame N's Present Position replies (`Driver.cycle_start` .. `cycle_finish`), the
pipeline runs frame N+1's muscle model, calibration and a **speculative** gate check: against the command
just sent (N's) and the health the gate used for N. The gate's step memory is put back at once, so the
gate is never left in a speculative state. At step N+1 the speculation is used only if it is exactly what
a check made then would be: the same AUs, the same last command (the driver re-pinned / eased nothing),
the same health (no new telemetry changed it) and the gate's step memory untouched since (no hold/reset).
Otherwise the gate checks afresh. So every command is still checked against the last command actually
sent, with the health of the last cycle; the overlap only moves *when* the same computation runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from servoface.sim.gate import ServoHealth, Verdict

StepState = tuple[np.ndarray | None, np.ndarray]  # TwinGate.step_state()


@dataclass(frozen=True)
class Ahead:
    """Frame N+1 as computed during frame N's wait."""

    aus: dict[str, float]
    targets: dict[str, float]
    clamped: dict[str, float]
    clamp_reasons: tuple[str, ...]
    requested: dict[int, int]
    timings_ms: dict[str, float]  # muscle_ms, calibration_ms, gate_ms (as spent during the wait)
    verdict: Verdict | None  # None: the speculative check could not run (then the step checks)
    last_goals_tick: dict[int, int]
    health: dict[int, ServoHealth] | None
    state_before: StepState
    state_after: StepState
    plan_s: float | None = None  # the elapsed time the check assumed (None: a whole period, per-frame caps)
    fraction_before: float = 1.0  # the gate's last-frame fraction the check started from

    def verdict_for(
        self, last_goals_tick: Mapping[int, int], health: Mapping[int, ServoHealth] | None, state: StepState
    ) -> Verdict | None:
        """The speculative verdict if its inputs are exactly the step's, else None."""
        if self.verdict is None or dict(last_goals_tick) != self.last_goals_tick:
            return None
        if (None if health is None else dict(health)) != self.health or not same_state(state, self.state_before):
            return None
        return self.verdict


def same_state(a: StepState, b: StepState) -> bool:
    if (a[0] is None) != (b[0] is None):
        return False
    if a[0] is not None and b[0] is not None and not np.array_equal(a[0], b[0]):
        return False
    return bool(np.array_equal(a[1], b[1]))
