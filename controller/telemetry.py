"""The driver's snapshot turned into what the twin gate reads: per-servo health (temperature, load)."""

from __future__ import annotations

from collections.abc import Mapping

from servoface.hardware.snapshot import ChainSnapshot, FaultKind, ServoState, peek_state
from servoface.sim.gate import HealthPolicy, ServoHealth

_HOT = {FaultKind.OVERHEATING, FaultKind.THERMAL_DERATE, FaultKind.THERMAL_TORQUE_OFF}
_OVERLOADED = {FaultKind.OVERLOAD, FaultKind.LOAD_BACKOFF}


def gate_health(
    snapshot: ChainSnapshot, temperature_limits_c: Mapping[int, float], ids: frozenset[int] | None = None
) -> dict[int, ServoHealth]:
    """Health of every servo the snapshot has telemetry for (and, when given, that is in ``ids``).

    A servo the driver flags hot / derated / overloaded is passed on as such; the gate then narrows its
    range and speed. Servos without a temperature reading yet are left out (no news is not bad news).
    """
    out: dict[int, ServoHealth] = {}
    for state in snapshot:
        if ids is not None and state.servo_id not in ids:
            continue
        if state.temperature_c is None or state.servo_id not in temperature_limits_c:
            continue
        out[state.servo_id] = _servo_health(state, temperature_limits_c[state.servo_id])
    return out


def _servo_health(state: ServoState, limit_c: float) -> ServoHealth:
    load = abs(state.load_fraction) if state.load_fraction is not None else 0.0
    return ServoHealth(
        temperature_c=float(state.temperature_c if state.temperature_c is not None else 0.0),
        temperature_limit_c=float(limit_c),
        load_ratio=float(load),
        overloaded=bool(state.faults & _OVERLOADED),
        hot=bool(state.faults & _HOT) or state.derated,
    )


class StrainedHealth:
    """`gate_health` cut down to what the gate reads: the servos its policy finds strained.

    The gate uses health only to narrow strained servos (`servoface.sim.gate.health.derate` skips the
    others), so the verdict for the strained subset is the verdict for the whole (tested on random
    telemetry). The subset is mostly empty, so it stays equal from frame to frame while the load readings
    move, and a speculative verdict computed with it stays usable (`pipeline_ahead`). A servo's record is
    rebuilt only when what it is made of changed (temperature, load, faults, derated, limit); the same state
    object as the last frame's (the driver keeps it while only position and goal move) is not even compared."""

    def __init__(self, ids: frozenset[int]) -> None:
        self.ids = ids
        # per servo: (the state last seen, its limit, what its record is made of, the record if strained)
        self._records: dict[int, tuple[ServoState, float, tuple[object, ...], ServoHealth | None]] = {}
        self._policy: HealthPolicy | None = None

    def __call__(
        self, snapshot: ChainSnapshot, temperature_limits_c: Mapping[int, float], policy: HealthPolicy
    ) -> dict[int, ServoHealth]:
        if policy is not self._policy:  # another gate (a new calibration): judge every servo afresh
            self._records.clear()
            self._policy = policy
        limits, ids, records = temperature_limits_c, self.ids, self._records
        out: dict[int, ServoHealth] = {}
        servos = snapshot.servos
        for sid in servos:
            if sid not in ids:
                continue
            peeked = peek_state(servos, sid)  # health is made of slow fields only: no state built
            if peeked is None:
                continue
            state = peeked[0]
            if state.temperature_c is None:
                continue
            limit_c = limits.get(sid)
            if limit_c is None:
                continue
            kept = records.get(sid)
            if kept is not None and kept[0] is state and kept[1] == limit_c:  # the same (frozen) state as last
                if kept[3] is not None:  # time: its slow fields did not change, nor did the verdict
                    out[sid] = kept[3]
                continue
            key = (state.temperature_c, state.load_fraction, state.faults, state.derated, limit_c)
            if kept is None or kept[2] != key:
                health = _servo_health(state, limit_c)
                kept = (
                    state,
                    limit_c,
                    key,
                    health if health.strained(policy.hot_margin_c, policy.load_limit) else None,
                )
            else:
                kept = (state, limit_c, key, kept[3])
            records[sid] = kept
            if kept[3] is not None:
                out[sid] = kept[3]
        return out
