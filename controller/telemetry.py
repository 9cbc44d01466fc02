"""The driver's snapshot turned into what the twin gate reads: per-servo health (temperature, load)."""

from __future__ import annotations

from collections.abc import Mapping

from servoface.hardware.snapshot import ChainSnapshot, FaultKind
from servoface.sim.gate import ServoHealth

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
        load = abs(state.load_fraction) if state.load_fraction is not None else 0.0
        out[state.servo_id] = ServoHealth(
            temperature_c=float(state.temperature_c),
            temperature_limit_c=float(temperature_limits_c[state.servo_id]),
            load_ratio=float(load),
            overloaded=bool(state.faults & _OVERLOADED),
            hot=bool(state.faults & _HOT) or state.derated,
        )
    return out
