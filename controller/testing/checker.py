"""`WireChecker`: the ``servo_wire`` fixture. Binds a chain (emulated, or real servos read back) to the
limits its goals are checked against; every ``assert_*`` takes a fresh record unless given one."""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping
from typing import Any, Protocol

from servoface.testing import wire
from servoface.testing.limits import WireLimits
from servoface.testing.record import WireRecord

POLL_S = 0.05


class Recorded(Protocol):
    def record(self) -> WireRecord: ...


class WireChecker:
    """Assertions on what reached the servos of ``chain``, against ``limits``."""

    def __init__(self, chain: Recorded, limits: WireLimits) -> None:
        self.chain = chain
        self.limits = limits

    def record(self) -> WireRecord:
        return self.chain.record()

    def goals(self, record: WireRecord | None = None) -> list[tuple[float, int, int]]:
        """(t_s, servo_id, goal_tick) of every goal the servos received, in wire order."""
        rec: WireRecord = record or self.record()
        return list(rec.goal_writes())

    def _ids(self, ids: Iterable[int] | None, record: WireRecord) -> list[int]:
        return sorted(record.end) if ids is None else [int(i) for i in ids]

    # ---- the history -------------------------------------------------------------------------------------
    def assert_goals_within_limits(self, record: WireRecord | None = None) -> None:
        """Every goal inside its servo's calibrated (or configured) limits."""
        rec = record or self.record()
        if wire.observed_or_warn(rec, "goals within limits"):
            wire.fail("goals outside the limits", wire.goal_limit_violations(rec, self.limits), rec)

    def assert_goal_steps_within_caps(self, record: WireRecord | None = None) -> None:
        """Consecutive goals of each servo within the gate's per-frame speed and acceleration caps (at the
        limits' ``rate_hz``: one goal write counts as one frame)."""
        rec = record or self.record()
        if not wire.observed_or_warn(rec, "goal steps within the caps"):
            return
        wire.warn_uncapped(self.limits)
        wire.fail("goal steps beyond the speed/acceleration caps", wire.goal_step_violations(rec, self.limits), rec)

    def assert_no_goal_while_torque_off(self, record: WireRecord | None = None, *, pin_tolerance_tick: int = 1) -> None:
        """No goal reached a servo with its torque off, except pinning it where it stood before torque-on."""
        rec = record or self.record()
        if wire.observed_or_warn(rec, "no goal while torque off"):
            violations = wire.torque_off_goal_violations(rec, self.limits, pin_tolerance_tick=pin_tolerance_tick)
            wire.fail("goals written while torque was off", violations, rec)

    def assert_safe(self, record: WireRecord | None = None, *, min_goals: int = 1) -> WireRecord:
        """All three history checks at once; at least ``min_goals`` goals must have reached the servos (a
        check of nothing is not a pass). Returns the record checked."""
        rec = record or self.record()
        if not wire.observed_or_warn(rec, "safe goals"):
            return rec
        n = len(rec.goals or ())
        if n < min_goals:
            raise AssertionError(f"only {n} goal write(s) reached the servos ({rec.source}); expected >= {min_goals}")
        wire.warn_uncapped(self.limits)
        violations = [
            *wire.goal_limit_violations(rec, self.limits),
            *wire.goal_step_violations(rec, self.limits),
            *wire.torque_off_goal_violations(rec, self.limits),
        ]
        wire.fail("unsafe goals on the wire", violations, rec)
        return rec

    # ---- the end state -----------------------------------------------------------------------------------
    def assert_torque(
        self, *, on: Iterable[int] = (), off: Iterable[int] = (), record: WireRecord | None = None
    ) -> None:
        rec = record or self.record()
        wire.fail("torque state at the end", wire.torque_violations(rec, self.limits, on=on, off=off), rec)

    def assert_torque_off(self, ids: Iterable[int] | None = None, *, record: WireRecord | None = None) -> None:
        """Torque off at the end on every servo (or ``ids``): nothing left holding when the code is done."""
        rec = record or self.record()
        self.assert_torque(off=self._ids(ids, rec), record=rec)

    def assert_torque_on(self, ids: Iterable[int] | None = None, *, record: WireRecord | None = None) -> None:
        rec = record or self.record()
        self.assert_torque(on=self._ids(ids, rec), record=rec)

    def assert_final_positions(
        self, expected_tick: Mapping[int, int], *, tolerance_tick: int = 2, within_s: float = 0.0
    ) -> WireRecord:
        """Each servo of ``expected_tick`` stands within ``tolerance_tick`` of it (polled for up to
        ``within_s`` of real time while servos are still moving)."""
        return self._positions(expected_tick, tolerance_tick, within_s, "expected", "final positions")

    def assert_matches_twin(self, face: Any, *, tolerance_tick: int = 2, within_s: float = 0.0) -> WireRecord:
        """The servos stand where the twin has them: at the gate's last goals (``face.pipeline``), and so at
        the twin's actuator targets (deg/mm, shown in the message)."""
        pipeline = face.pipeline
        goals = dict(pipeline.last_goals_tick)
        rec = self._positions(
            goals, tolerance_tick, within_s, "the twin has it at", "positions against the twin", pipeline
        )
        return rec

    def _positions(
        self, expected: Mapping[int, int], tol: int, within_s: float, what: str, title: str, pipeline: Any = None
    ) -> WireRecord:
        deadline = time.monotonic() + max(0.0, float(within_s))
        while True:
            rec = self.record()
            violations = wire.position_violations(rec, self.limits, expected, tolerance_tick=tol, what=what)
            if not violations or time.monotonic() >= deadline:
                break
            time.sleep(POLL_S)
        if violations and pipeline is not None:
            violations = _with_targets(violations, rec, expected, pipeline)
        wire.fail(title, violations, rec)
        return rec


def _with_targets(violations: list[str], rec: WireRecord, goals: Mapping[int, int], pipeline: Any) -> list[str]:
    """Add the twin's actuator targets (deg or mm) of where the servos stand and where the twin has them."""
    cal = pipeline.calibration
    try:
        twin = pipeline.gate.twin_pose(dict(goals))[2]
        stands = cal.goals_to_targets({sid: rec.end[sid].present_tick for sid in goals if sid in rec.end}, clip=True)
    except Exception:  # noqa: BLE001 - the targets only decorate a failure that is already being reported
        return violations
    notes = [
        f"  '{role}': stands at {stands[role]:.2f} {cal[role].unit}, "
        f"the twin's target {twin[role]:.2f} {cal[role].unit}"
        for role in sorted(stands)
        if role in twin and abs(stands[role] - twin[role]) > cal[role].target_resolution()
    ]
    return violations + notes
