"""What the driver knows about the chain after a cycle: typed, frozen, safe to hand to other threads."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from enum import Enum
from types import MappingProxyType
from typing import Any

from servoface.hardware.bus import BusCounters
from servoface.hardware.registers import HardwareErrorBits


class FaultKind(Enum):
    """Every condition the fault policy reacts to (see README "Faults")."""

    TIMEOUT = "timeout"  # a transaction got no reply (retried)
    CORRUPT = "corrupt"  # a reply failed its CRC / was truncated (retried, counted)
    MISSING = "missing"  # a servo stopped answering: excluded from group reads, re-probed
    RECONNECTED = "reconnected"  # a missing servo answers again: re-configured, goal re-pinned
    DISCONNECTED = "disconnected"  # the port failed: every servo missing, port re-opened periodically
    OVERLOAD = "overload"  # Hardware Error Status overload bit (servo shut its torque off)
    LOAD_BACKOFF = "load_backoff"  # load above the threshold: goals eased toward present position
    OVERHEATING = "overheating"  # overheating bit, or temperature at the limit
    THERMAL_DERATE = "thermal_derate"  # temperature rising toward the limit: profile velocity lowered
    THERMAL_TORQUE_OFF = "thermal_torque_off"  # predicted to reach the limit soon: torque off until cool
    VOLTAGE_LOW = "voltage_low"  # a supply reading below the low threshold
    VOLTAGE_HIGH = "voltage_high"  # a supply reading above the high threshold
    INPUT_VOLTAGE = "input_voltage_error"  # the servo's own Input Voltage Error bit (whatever the reading)
    UNREACHED = "unreached"  # a stop could not turn this servo's torque off (it may still be powered)
    HARDWARE_ERROR = "hardware_error"  # encoder / electrical shock: latched, needs `clear_fault`
    REBOOTED = "rebooted"  # the driver rebooted a servo to clear its error
    RECOVERED = "recovered"  # a servo returned to service (torque back on, goal re-pinned)
    LATCHED = "latched"  # too many reboots, or a fault that needs a human: stays torque-off
    SENTINEL = "sentinel"  # the position sentinel (Indirect Data) is off for the chain: reset seen by status reads

    __hash__ = object.__hash__  # singletons: identity hash at C speed (sets of them are checked every cycle)


@dataclass(frozen=True)
class FaultEvent:
    """One reaction of the fault policy. ``servo_id`` is None for chain-wide events."""

    t_s: float
    servo_id: int | None
    kind: FaultKind
    reaction: str

    def __str__(self) -> str:
        who = "chain" if self.servo_id is None else f"servo {self.servo_id}"
        return f"{self.t_s:.3f}s {who}: {self.kind.value} -> {self.reaction}"


@dataclass(frozen=True)
class ServoState:
    """One servo. Values are None until first read; ``*_t_s`` say when they were read (driver clock)."""

    servo_id: int
    position_tick: int | None
    goal_tick: int | None  # last goal actually written
    velocity_rpm: float | None
    current_ma: float | None  # None on models that report load instead
    load_fraction: float | None  # signed: current / current limit, or load / 100 %
    temperature_c: int | None
    voltage_v: float | None
    hardware_error: HardwareErrorBits
    moving: bool | None
    torque_on: bool
    missing: bool
    stale: bool  # the last position read of this servo failed
    derated: bool
    faults: frozenset[FaultKind]  # active conditions
    position_t_s: float | None
    telemetry_t_s: float | None  # last slow telemetry (temperature / voltage) read
    seconds_to_temperature_limit: float | None  # predicted from the rate of rise; None if not rising

    @property
    def ok(self) -> bool:
        return not self.missing and not self.faults and self.hardware_error == HardwareErrorBits.NONE


# What `ServoRecord.freeze_lazy` captures while only the position moved: (the last state, position_tick,
# position_t_s, goal_tick, stale) — the state is built from it when first asked for (`LazyServoStates`).
StateCapture = tuple[ServoState, Any, Any, Any, bool]


def build_state(capture: StateCapture) -> ServoState:
    """The `ServoState` a capture stands for: the last state's fields with the four that moved replaced."""
    last, position_tick, position_t_s, goal_tick, stale = capture
    fields = last.__dict__.copy()
    fields["position_tick"] = position_tick
    fields["position_t_s"] = position_t_s
    fields["goal_tick"] = goal_tick
    fields["stale"] = stale
    state: ServoState = object.__new__(ServoState)
    object.__setattr__(state, "__dict__", fields)  # a frozen dataclass: its fields, bypassing __init__
    return state


class LazyServoStates(Mapping[int, ServoState]):
    """A snapshot's servos (read-only mapping id -> `ServoState`) whose states are built on first access from
    what the cycle captured (immutable values, so the states are the same whenever, and on whichever
    thread, they are built; a race builds two equal states). A caller that never looks at a servo's state
    in a cycle (a back-to-back loop) does not pay for building it."""

    __slots__ = ("_items",)

    def __init__(self, items: dict[int, ServoState | StateCapture]) -> None:
        self._items = items

    def __getitem__(self, servo_id: int) -> ServoState:
        item = self._items[servo_id]
        if type(item) is tuple:
            item = build_state(item)
            self._items[servo_id] = item
        return item  # type: ignore[return-value]

    def peek(self, servo_id: int) -> tuple[ServoState, Any]:
        """(a state with this servo's fields except the four a capture holds, its ``goal_tick``) without
        building its state: the capture's last state, or the state itself. KeyError for an unknown id."""
        item = self._items[servo_id]
        if isinstance(item, tuple):
            return item[0], item[3]
        return item, item.goal_tick

    def __iter__(self) -> Iterator[int]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, servo_id: object) -> bool:
        return servo_id in self._items

    def __repr__(self) -> str:
        return f"{{{', '.join(f'{k!r}: {v!r}' for k, v in self.items())}}}"


def peek_state(servos: Mapping[int, ServoState], servo_id: int) -> tuple[ServoState, Any] | None:
    """(a state whose fields are this servo's except ``position_tick``, ``position_t_s``, ``goal_tick`` and
    ``stale``, its ``goal_tick``), or None for an id not in ``servos``. For a snapshot of the driver's
    (`LazyServoStates`) the state is not built (a per-frame reader of slow fields and goals, e.g. health,
    pays for no state); any other mapping gives the state itself."""
    if type(servos) is LazyServoStates:
        try:
            return servos.peek(servo_id)
        except KeyError:
            return None
    state = servos.get(servo_id)
    return None if state is None else (state, state.goal_tick)


@dataclass(frozen=True)
class ChainSnapshot:
    """The whole chain after one `Driver.cycle`. ``events``: the fault reactions of that cycle only."""

    t_s: float
    cycle: int
    servos: Mapping[int, ServoState]
    events: tuple[FaultEvent, ...]
    stats: BusCounters
    bus_connected: bool

    def __post_init__(self) -> None:
        object.__setattr__(self, "servos", MappingProxyType(dict(self.servos)))

    @classmethod
    def owning(
        cls,
        t_s: float,
        cycle: int,
        servos: dict[int, ServoState | StateCapture],
        events: tuple[FaultEvent, ...],
        stats: BusCounters,
        bus_connected: bool,
    ) -> ChainSnapshot:
        """A snapshot that takes ``servos`` as its own (the caller keeps no reference to the dict): equal to
        ``ChainSnapshot(...)`` without its defensive copy (the driver builds one per cycle); its values are
        states or captures of them (`StateCapture`), built on first access (`LazyServoStates`)."""
        snap: ChainSnapshot = object.__new__(cls)
        object.__setattr__(
            snap,
            "__dict__",
            {
                "t_s": t_s,
                "cycle": cycle,
                "servos": LazyServoStates(servos),
                "events": events,
                "stats": stats,
                "bus_connected": bus_connected,
            },
        )
        return snap

    def __getitem__(self, servo_id: int) -> ServoState:
        return self.servos[servo_id]

    def __iter__(self) -> Iterator[ServoState]:
        return iter(self.servos.values())

    def positions_tick(self) -> dict[int, int]:
        """Last known position of every servo that has one."""
        return {s.servo_id: s.position_tick for s in self if s.position_tick is not None}

    @property
    def missing(self) -> tuple[int, ...]:
        return tuple(s.servo_id for s in self if s.missing)
