"""Which chain a test gets: a built-in head, a profile folder or an explicit servo list; in-process or on a
pty served by another process; real or manual clock; faults scheduled from the start. Resolved per test
from ``@pytest.mark.servoface(...)`` (closest marker wins: test, class, module), then the ini file
(``[tool.pytest.ini_options] servoface_head = "my_head/"``), then the defaults."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from servoface.testing.chains import CLOCKS, TRANSPORTS
from servoface.testing.errors import TestKitConfigError

DEFAULT_IDS = (1, 2, 3, 4)
DEFAULT_MODEL = "XL330-M288"
DEFAULT_LIMITS_TICK = (1024, 3072)
MARKER_KEYS = frozenset(
    {
        "head",
        "servos",
        "model",
        "transport",
        "clock",
        "wire_time",
        "baud",
        "goal_limit",
        "rate_hz",
        "limits_tick",
        "faults",
    }
)
INI_KEYS = ("head", "servos", "model", "transport", "clock")


@dataclass(frozen=True)
class FaultPlan:
    """A fault the chain gets when it is created: ``kind`` on ``servo_id`` from ``after_s`` (chain time
    from creation) for ``duration_s`` (None = for good); ``options``: ``delay_s``, ``drop_bytes``."""

    servo_id: int
    kind: str
    after_s: float = 0.0
    duration_s: float | None = None
    options: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def parse(cls, item: Any, where: str) -> FaultPlan:
        from servoface.hardware.emulator import FAULT_KINDS

        if isinstance(item, FaultPlan):
            plan = item
        elif isinstance(item, Mapping):
            extra = set(item) - {"servo_id", "kind", "after_s", "duration_s", "delay_s", "drop_bytes"}
            if extra or "servo_id" not in item or "kind" not in item:
                raise TestKitConfigError(
                    f"{where}: expected {{servo_id, kind, after_s?, duration_s?, delay_s?, drop_bytes?}}, "
                    f"got {dict(item)!r}"
                )
            opts = {k: float(item[k]) for k in ("delay_s", "drop_bytes") if k in item}
            plan = cls(
                int(item["servo_id"]), str(item["kind"]), float(item.get("after_s", 0.0)), item.get("duration_s"), opts
            )
        elif isinstance(item, tuple | list) and 2 <= len(item) <= 4:
            plan = cls(
                int(item[0]), str(item[1]), float(item[2]) if len(item) > 2 else 0.0, item[3] if len(item) > 3 else None
            )
        else:
            raise TestKitConfigError(f"{where}: expected (servo_id, kind, after_s, duration_s) or a dict, got {item!r}")
        if plan.kind not in FAULT_KINDS:
            raise TestKitConfigError(f"{where}: fault kind {plan.kind!r}; expected one of {sorted(FAULT_KINDS)}")
        if not (math.isfinite(plan.after_s) and plan.after_s >= 0):
            raise TestKitConfigError(f"{where}: after_s {plan.after_s!r}; expected a finite number >= 0")
        return plan


@dataclass(frozen=True)
class ServofaceConfig:
    """The resolved settings of one test (``servoface_config`` fixture; override it to build your own)."""

    head: str | None = None
    servos: tuple[tuple[int, str], ...] | None = None  # explicit (id, model) list; None = the head's or 1-4
    transport: str = "inprocess"
    clock: str = "real"
    wire_time: bool = True
    baud: int = 1_000_000
    goal_limit: str = "reject"
    rate_hz: float = 50.0
    limits_tick: tuple[int, int] = DEFAULT_LIMITS_TICK  # configured limits of an explicit servo list
    faults: tuple[FaultPlan, ...] = ()

    def servo_list(self) -> tuple[tuple[int, str], ...]:
        return self.servos if self.servos is not None else tuple((i, DEFAULT_MODEL) for i in DEFAULT_IDS)


def parse_servos(value: Any, model: str, where: str) -> tuple[tuple[int, str], ...]:
    """``"1-4,7"``, ``"1:XL330-M288,2:XL430-W250"``, ``[1, 2]`` or ``[(1, "XL330-M288"), ...]``."""
    from servoface.hardware.bus import ids_from_spec

    out: list[tuple[int, str]] = []
    try:
        if isinstance(value, str):
            for part in filter(None, (p.strip() for p in value.split(","))):
                if ":" in part:
                    sid, m = part.split(":", 1)
                    out.append((int(sid), m.strip()))
                else:
                    out += [(i, model) for i in ids_from_spec(part)]
        else:
            for item in value:
                if isinstance(item, tuple | list):
                    out.append((int(item[0]), str(item[1])))
                elif isinstance(item, int) and not isinstance(item, bool):
                    out.append((item, model))
                else:
                    raise ValueError(f"item {item!r}")
    except (TypeError, ValueError) as err:
        raise TestKitConfigError(
            f"{where}: servos {value!r}: expected '1-4,7', '1:XL330-M288,2:XL430-W250', [1, 2] or [(1, model)] ({err})"
        ) from err
    ids = [sid for sid, _ in out]
    if not out or len(set(ids)) != len(ids):
        raise TestKitConfigError(f"{where}: servos {value!r}: expected at least one id, each once")
    return tuple(out)


def resolve(marker: Mapping[str, Any], ini: Mapping[str, str], *, wants_face: bool) -> ServofaceConfig:
    """Marker keyword arguments over ini values over defaults. ``wants_face``: the test asked for a ``face``
    (a Face needs a head: the built-in human head unless one is configured)."""
    unknown = sorted(set(marker) - MARKER_KEYS)
    if unknown:
        raise TestKitConfigError(
            f"@pytest.mark.servoface: unknown argument(s) {unknown}; expected some of {sorted(MARKER_KEYS)}"
        )
    merged: dict[str, Any] = {k: v for k, v in ini.items() if v not in ("", None)}
    merged.update(marker)
    where = "@pytest.mark.servoface" if marker else "servoface ini options"
    model = str(merged.get("model", DEFAULT_MODEL))
    servos = parse_servos(merged["servos"], model, where) if merged.get("servos") not in (None, "") else None
    head = merged.get("head") or None
    if head is not None and servos is not None:
        raise TestKitConfigError(f"{where}: give head= or servos=, not both (a head brings its own servos)")
    if head is None and servos is None and wants_face:
        head = "human"
    transport = str(merged.get("transport", "inprocess"))
    if transport not in TRANSPORTS:
        raise TestKitConfigError(f"{where}: transport {transport!r}; expected one of {TRANSPORTS}")
    clock = str(merged.get("clock", "real"))
    if clock not in CLOCKS:
        raise TestKitConfigError(f"{where}: clock {clock!r}; expected one of {CLOCKS}")
    wire_time = merged.get("wire_time", clock == "real")
    if not isinstance(wire_time, bool):
        raise TestKitConfigError(f"{where}: wire_time {wire_time!r}; expected True or False")
    lo_hi = tuple(merged.get("limits_tick", DEFAULT_LIMITS_TICK))
    if len(lo_hi) != 2 or not 0 <= int(lo_hi[0]) < int(lo_hi[1]) <= 4095:
        raise TestKitConfigError(f"{where}: limits_tick {lo_hi!r}; expected (min, max) with 0 <= min < max <= 4095")
    faults = tuple(FaultPlan.parse(f, f"{where}: faults[{i}]") for i, f in enumerate(merged.get("faults", ())))
    return ServofaceConfig(
        head=None if head is None else str(head),
        servos=servos,
        transport=transport,
        clock=clock,
        wire_time=wire_time,
        baud=int(merged.get("baud", 1_000_000)),
        goal_limit=str(merged.get("goal_limit", "reject")),
        rate_hz=float(merged.get("rate_hz", 50.0)),
        limits_tick=(int(lo_hi[0]), int(lo_hi[1])),
        faults=faults,
    )
