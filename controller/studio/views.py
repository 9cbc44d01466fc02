"""What the studio tells the browser, as JSON-ready dicts: the head (AUs grouped by face region, servos
with their calibrated limits, the expression library), telemetry, frames and the service's state."""

from __future__ import annotations

from typing import Any

from servoface.calibration import HeadCalibration
from servoface.controller.pipeline import FrameTrace
from servoface.controller.service import HeadService, ServiceStatus
from servoface.hardware.snapshot import ChainSnapshot, FaultEvent
from servoface.sim.head import Head
from servoface.sim.rig import JointActuator

HUMAN_REGIONS: dict[str, tuple[int, ...]] = {
    "brows": (1, 2, 4),
    "lids": (5, 7, 41, 42, 43, 44, 45, 46),
    "eyes": (61, 62, 63, 64, 65, 66),
    "nose": (9, 11, 38, 39),
    "cheeks": (6, 13, 14, 34),
    "lips": (10, 12, 15, 16, 17, 18, 20, 22, 23, 24, 25, 28),
    "jaw": (19, 26, 27),
    "head": (51, 52, 53, 54, 55, 56, 57, 58),
}
DOG_REGIONS: dict[str, tuple[int, ...]] = {
    "lids": (4, 15),
    "eyes": (12, 13, 14),
    "ears": (5, 6),
    "nose": (3,),
    "lips": (1, 2),
    "jaw": (7, 8, 16, 17, 18, 19),
    "head": (9, 10, 11),
}


def regions_for(face_type: str) -> dict[str, tuple[int, ...]]:
    return DOG_REGIONS if face_type == "dog" else HUMAN_REGIONS


def _region_of(number: int, regions: dict[str, tuple[int, ...]]) -> str:
    for name, numbers in regions.items():
        if number in numbers:
            return name
    return "other"


def au_entries(head: Head, names: frozenset[str]) -> list[dict[str, Any]]:
    """One entry per plain AU the head accepts (its ``L``/``R`` variants flagged as ``sided``)."""
    from servoface.controller.au_names import au_number, au_ranges, intensity_range

    regions = regions_for(head.face_type)
    labels: dict[int, str] = {}
    try:
        from servoface.sim.au import load_au_table

        table = load_au_table(head.au_table_path or head.face_type)
        labels = {e.number: e.action.name for e in table.entries.values()}
    except Exception:  # noqa: BLE001 - labels are a nicety; the names still come from the validator
        pass
    lo, hi = intensity_range(head.face_type)
    special = au_ranges(head.face_type)
    plain = sorted((n for n in names if n[-1] not in "LR"), key=au_number)
    out = []
    for name in plain:
        rng = special.get(name, (lo, hi))
        number = au_number(name)
        out.append(
            {
                "name": name,
                "min": float(rng[0]),
                "max": float(rng[1]),
                "region": _region_of(number, regions),
                "label": labels.get(number, ""),
                "sided": f"{name}L" in names and f"{name}R" in names,
            }
        )
    return out


def servo_entries(head: Head, calibration: HeadCalibration) -> list[dict[str, Any]]:
    out = []
    for a in head.actuators:
        cal = calibration.by_id(a.servo.id)
        joint = isinstance(a, JointActuator)
        lower, upper, neutral = (
            (a.lower_deg, a.upper_deg, a.neutral_deg)
            if isinstance(a, JointActuator)
            else (a.lower_mm, a.upper_mm, a.neutral_mm)
        )
        out.append(
            {
                "id": a.servo.id,
                "role": a.role,
                "model": a.servo.model,
                "unit": "deg" if joint else "mm",
                "min_tick": int(cal.min_tick),
                "max_tick": int(cal.max_tick),
                "neutral_tick": int(cal.neutral_tick),
                "lower": float(lower),
                "upper": float(upper),
                "neutral": float(neutral),
            }
        )
    return out


def head_info(service: HeadService, render: tuple[int, int]) -> dict[str, Any]:
    from servoface.controller.service import DEFAULT_TRACKS
    from servoface.sim.expressions import load_library

    head = service.head
    regions = regions_for(head.face_type)
    try:
        expressions = sorted(load_library(head.expressions_path or head.face_type))
    except Exception:  # noqa: BLE001 - a head without a library still has sliders
        expressions = []
    return {
        "name": head.name,
        "face_type": head.face_type,
        "rate_hz": service.rate_hz,
        "render": {"width": render[0], "height": render[1]},
        "aus": au_entries(head, service.validator.names),
        "regions": list(regions),
        "expressions": expressions,
        "tracks": [t.name for t in DEFAULT_TRACKS if t.name in service.tracks.slots] or list(service.tracks.slots),
        "servos": servo_entries(head, service.pipeline.calibration),
    }


def _round(value: float | None, digits: int = 3) -> float | None:
    return None if value is None else round(float(value), digits)


def telemetry(snapshot: ChainSnapshot | None, roles: dict[int, str]) -> dict[str, Any]:
    if snapshot is None:
        return {"t_s": None, "servos": []}
    servos = []
    for s in snapshot:
        servos.append(
            {
                "id": s.servo_id,
                "role": roles.get(s.servo_id, ""),
                "position_tick": s.position_tick,
                "goal_tick": s.goal_tick,
                "load_pct": None if s.load_fraction is None else round(100.0 * s.load_fraction, 2),
                "current_ma": _round(s.current_ma, 1),
                "temperature_c": s.temperature_c,
                "voltage_v": _round(s.voltage_v, 2),
                "moving": s.moving,
                "torque_on": s.torque_on,
                "missing": s.missing,
                "faults": sorted(f.value for f in s.faults),
                "hardware_error": int(s.hardware_error),
            }
        )
    return {"t_s": round(snapshot.t_s, 4), "servos": servos}


def frame(trace: FrameTrace) -> dict[str, Any]:
    return {
        "type": "frame",
        "index": trace.index,
        "t_s": round(trace.t_s, 4),
        "verdict": trace.verdict,
        "checks": list(trace.checks),
        "reasons": list(trace.reasons),
        "aus": {k: round(v, 4) for k, v in trace.aus.items() if abs(v) > 1e-6},
        "goals_sent": {str(k): v for k, v in trace.goals_sent.items()},
    }


def verdict(trace: FrameTrace | None) -> dict[str, Any] | None:
    if trace is None:
        return None
    return {
        "index": trace.index,
        "verdict": trace.verdict,
        "checks": list(trace.checks),
        "reasons": list(trace.reasons),
    }


def tracks(status: ServiceStatus) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, view in status.tracks.items():
        out[name] = {
            "state": view.state,
            "source": view.source or "",
            "command_id": view.command_id,
            "scheduled": view.scheduled,
            "aus": {k: round(float(v), 4) for k, v in view.aus.items() if abs(v) > 1e-6},
        }
    return out


def fault(event: Any) -> dict[str, Any]:
    if isinstance(event, FaultEvent):
        return {
            "type": "fault",
            "t_s": round(event.t_s, 4),
            "kind": event.kind.value,
            "servo_id": event.servo_id,
            "detail": event.reaction,
        }
    return {
        "type": "fault",
        "t_s": round(float(getattr(event, "t_s", 0.0)), 4),
        "kind": str(getattr(event, "kind", "event")),
        "servo_id": None,
        "detail": str(getattr(event, "detail", "")),
    }
