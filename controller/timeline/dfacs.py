"""DFACS signed, ordered events -> timed per-AU keyframes (the dog's expressions, dfacs-dog.md §3-4).

An event names one AU and a signed target: ``AU7`` (drive it) or ``-AU7`` (its counter AU, a negative
value). Events fire IN ORDER; the face keeps every AU an event moved (AUs never named hold their value).

Default timing (:class:`EventTiming`; every number overridable, none is from the thesis, which publishes
no durations):

- event k starts ``spacing_s`` = 0.15 s after event k-1 ("near-simultaneous but ordered");
- each motion takes ``move_s`` = 0.30 s, minimum-jerk;
- an event on an AU (or AU group, see ``exclusive``) that is still moving waits until that motion ended
  plus ``dwell_s`` = 0.20 s. Head pitch/yaw/roll (AU9, AU10, AU11) form one exclusive group, so they never
  move at the same time (affection), and repeating an AU gives equal open/close phases (smelling);
- after the last motion the pose holds for ``hold_s`` = 1.0 s; with ``release_s`` set, every AU then
  returns to 0 over that time (None = stay, the next expression starts from here — Barker's rule);
- ``intensity`` = 0.8 is the magnitude of events that give none;
- AU15 (blink) is a pulse: closes and reopens over ``pulse_s`` = 0.25 s; AU16 (lick) cycles down/up
  ``iterations`` times (default 2) of ``cycle_s`` = 0.5 s each.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from servoface.controller.au_names import au_number, canonical_au
from servoface.controller.errors import FrameError, TimelineError
from servoface.controller.timeline.clip import ChannelClip, Key
from servoface.controller.timeline.easing import Easing, linear, min_jerk

PULSE_AUS = frozenset({15})
CYCLIC_AUS = frozenset({16})

#: Londra's recipes, thesis Table 5.5 (event orders; "-n" = counter of AU n). MUSCLES' library
#: (``sim/expressions``) is authoritative once it lands; these are the fallback and the test fixture.
LONDRA_RECIPES: dict[str, tuple[int, ...]] = {
    "anger": (14, 4, 1, 2, 5, 7, 18),
    "anger_without_tongue": (14, 4, 1, 2, 5, 7),
    "affection_i": (-14, 9, -9, 9, -9, 10, -10, 10, -10, 9),
    "affection_ii": (-14, -9, 9, 7, 16),
    "attention": (12, 13, 6, 11, 9),
    "fear": (-14, -5, -9),
    "happiness": (6, 9),
    "yawning": (17, 7, -17, 19),
    "smelling": (3, -3),
}

_TOKEN_RE = re.compile(r"^\s*([+-]?)\s*(AU\d+[LR]?)\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class Event:
    """One DFACS event: ``au`` (canonical, e.g. "AU7") driven to ``value`` (signed, -1..1).

    ``value`` None = ``sign`` times the timing's default intensity. ``iterations`` applies to AU16.
    """

    au: str
    sign: int = 1
    value: float | None = None
    iterations: int | None = None

    def target(self, timing: EventTiming) -> float:
        return self.value if self.value is not None else self.sign * timing.intensity

    @property
    def number(self) -> int:
        return au_number(self.au)


@dataclass(frozen=True)
class EventTiming:
    """How ordered events become time. See the module docstring for the defaults and their meaning."""

    spacing_s: float = 0.15
    move_s: float = 0.30
    dwell_s: float = 0.20
    hold_s: float = 1.0
    release_s: float | None = None
    intensity: float = 0.8
    pulse_s: float = 0.25
    cycle_s: float = 0.5
    iterations: int = 2
    easing: Easing = min_jerk
    exclusive: tuple[frozenset[int], ...] = field(default_factory=lambda: (frozenset({9, 10, 11}),))

    def __post_init__(self) -> None:
        for name in ("spacing_s", "move_s", "dwell_s", "hold_s", "pulse_s", "cycle_s"):
            _check_nonneg(getattr(self, name), name)
        if self.release_s is not None:
            _check_nonneg(self.release_s, "release_s")
        if not (isinstance(self.intensity, int | float) and 0.0 <= self.intensity <= 1.0):
            raise TimelineError(f"intensity: expected a magnitude 0..1, got {self.intensity!r}")
        if isinstance(self.iterations, bool) or not isinstance(self.iterations, int) or self.iterations < 1:
            raise TimelineError(f"iterations: expected an integer >= 1, got {self.iterations!r}")

    def group(self, au: str) -> str:
        """The serialisation key of an AU: its exclusive group, else the AU itself (AU5L and AU5R are
        independent; a bilateral AU5 waits for both)."""
        number = au_number(au)
        for i, members in enumerate(self.exclusive):
            if number in members:
                return f"group{i}"
        return au

    def with_overrides(self, **changes: Any) -> EventTiming:
        return replace(self, **changes)


def _finite(value: float) -> bool:
    """``math.isfinite`` that is False (not OverflowError) for an integer too large for a float."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _check_nonneg(value: Any, name: str) -> None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and _finite(value)
    if not ok or value < 0:
        raise TimelineError(f"{name}: expected a finite duration in seconds >= 0, got {value!r}")


def parse_event(token: Any, *, field: str = "event") -> Event:
    """An event from ``14`` / ``-14`` (thesis notation), ``"AU14"`` / ``"-AU14"``, or a mapping
    ``{au = "AU7", value = -0.6, iterations = 3}`` (value signed, -1..1)."""
    try:
        if isinstance(token, bool):
            raise TimelineError(f"{field}: expected an AU event, got {token!r}")
        if isinstance(token, int):
            if token == 0:
                raise TimelineError(f"{field}: 0 is not an AU; expected e.g. 14 or -14")
            return Event(f"AU{abs(token)}", 1 if token > 0 else -1)
        if isinstance(token, str):
            match = _TOKEN_RE.match(token)
            if match is None:
                raise TimelineError(f"{field}: {token!r} is not an event; expected 'AU14' or '-AU14' (counter)")
            return Event(canonical_au(match.group(2), field=field), -1 if match.group(1) == "-" else 1)
        if isinstance(token, Mapping):
            return _event_from_mapping(token, field)
    except FrameError as err:
        raise TimelineError(str(err)) from err
    raise TimelineError(f"{field}: expected an AU event like 'AU14', '-AU14', 14 or a table, got {token!r}")


def _event_from_mapping(token: Mapping[str, Any], field: str) -> Event:
    unknown = set(token) - {"au", "value", "iterations"}
    if unknown:
        raise TimelineError(f"{field}: unknown key(s) {sorted(unknown)}; expected au, value, iterations")
    if "au" not in token:
        raise TimelineError(f"{field}.au: missing; expected an AU name like 'AU7'")
    base = parse_event(token["au"], field=f"{field}.au")
    value = token.get("value")
    if value is not None:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and _finite(value)
        if not ok or not -1.0 <= value <= 1.0:
            raise TimelineError(f"{field}.value: expected a signed DFACS intensity -1..1, got {value!r}")
        value = float(value) * base.sign
    iterations = token.get("iterations")
    if iterations is not None and (isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1):
        raise TimelineError(f"{field}.iterations: expected an integer >= 1, got {iterations!r}")
    sign = base.sign if value is None else (-1 if value < 0 else 1)
    return Event(base.au, sign, value, iterations)


def parse_events(tokens: Iterable[Any], *, field: str = "events") -> tuple[Event, ...]:
    events = tuple(parse_event(t, field=f"{field}[{i}]") for i, t in enumerate(tokens))
    if not events:
        raise TimelineError(f"{field}: expected at least one event")
    return events


@dataclass(frozen=True)
class ScheduledEvent:
    """Where an event landed: motion from ``start_s`` to ``end_s`` towards ``target``."""

    event: Event
    start_s: float
    end_s: float
    target: float


def schedule(events: Sequence[Event], timing: EventTiming = EventTiming()) -> list[ScheduledEvent]:
    """Place ordered events in time (the rules in the module docstring)."""
    out: list[ScheduledEvent] = []
    busy_until: dict[str, float] = {}
    prev_onset = -math.inf
    for ev in events:
        onset = 0.0 if not out else prev_onset + timing.spacing_s
        group = timing.group(ev.au)
        blocking = [group]
        if group == ev.au:  # a bilateral AU waits for its sides and a side for the bilateral AU
            base = f"AU{ev.number}"
            blocking += [base] if ev.au != base else [f"{base}L", f"{base}R"]
        for key in blocking:
            if key in busy_until:
                onset = max(onset, busy_until[key] + timing.dwell_s)
        if ev.number in PULSE_AUS:
            length = timing.pulse_s
        elif ev.number in CYCLIC_AUS:
            length = timing.cycle_s * (ev.iterations or timing.iterations)
        else:
            length = timing.move_s
        out.append(ScheduledEvent(ev, onset, onset + length, ev.target(timing)))
        busy_until[group] = onset + length
        prev_onset = onset
    return out


def events_clip(
    events: Sequence[Event],
    timing: EventTiming = EventTiming(),
    *,
    repeat: int = 1,
    name: str = "events",
) -> ChannelClip:
    """Compile ordered events (the list repeated ``repeat`` times) to a clip that starts from the face."""
    if isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1:
        raise TimelineError(f"{name}.repeat: expected an integer >= 1, got {repeat!r}")
    if not events:
        raise TimelineError(f"{name}: expected at least one event")
    placed = schedule(list(events) * repeat, timing)
    keys: dict[str, list[Key]] = {}
    level: dict[str, float | None] = {}
    ease = timing.easing
    for p in placed:
        au, n = p.event.au, p.event.number
        chan = keys.setdefault(au, [Key(0.0, None)])
        before = level.get(au)
        chan.append(Key(p.start_s, before, linear))
        if n in PULSE_AUS:
            mid = (p.start_s + p.end_s) / 2
            chan += [Key(mid, p.target, ease), Key(p.end_s, before, ease)]
        elif n in CYCLIC_AUS:
            cycles = p.event.iterations or timing.iterations
            for c in range(cycles):
                t0 = p.start_s + c * timing.cycle_s
                chan += [Key(t0 + timing.cycle_s / 2, p.target, ease), Key(t0 + timing.cycle_s, before, ease)]
        else:
            chan.append(Key(p.end_s, p.target, ease))
            level[au] = p.target
    end = max(p.end_s for p in placed) + timing.hold_s
    duration = end
    if timing.release_s is not None:
        duration = end + timing.release_s
        for chan in keys.values():
            chan += [Key(end, chan[-1].value, linear), Key(duration, 0.0, ease)]
    return ChannelClip({au: tuple(k) for au, k in keys.items()}, duration, unlisted="hold", name=name)


def recipe_events(name: str, *, use_library: bool = True) -> tuple[Event, ...]:
    """The ordered events of a Londra expression: MUSCLES' library (``sim/expressions/dog.toml``, with its
    intensities) first, Table 5.5 with the default intensity as fallback (or with ``use_library=False``)."""
    library = _library_events() if use_library else {}
    if name in library:
        return library[name]
    if name not in LONDRA_RECIPES:
        known = sorted(set(LONDRA_RECIPES) | set(library))
        raise TimelineError(f"dog expression {name!r} is unknown; expected one of {', '.join(known)}")
    return parse_events(LONDRA_RECIPES[name], field=name)


def _library_events() -> dict[str, tuple[Event, ...]]:
    """Ordered event lists from ``servoface.sim.expressions`` if that module is present and exposes them."""
    try:
        from servoface.sim.expressions import load_library  # type: ignore[import-not-found,unused-ignore]
    except ImportError:
        return {}
    try:
        library = load_library("dog")
    except Exception:  # noqa: BLE001 - the library is optional here; fall back to Table 5.5
        return {}
    out: dict[str, tuple[Event, ...]] = {}
    for name, expr in dict(library).items():
        raw = getattr(expr, "events", None)
        if raw:
            try:
                out[str(name)] = parse_events(_event_tokens(raw), field=f"sim.expressions.{name}")
            except TimelineError:
                continue
    return out


def _event_tokens(raw: Iterable[Any]) -> list[Any]:
    tokens: list[Any] = []
    for item in raw:
        au = getattr(item, "au", None)
        if au is not None:
            value = getattr(item, "value", getattr(item, "intensity", None))
            tokens.append({"au": au} if value is None else {"au": au, "value": value})
        elif isinstance(item, tuple | list) and len(item) == 2:
            tokens.append({"au": item[0], "value": item[1]})
        else:
            tokens.append(item)
    return tokens
