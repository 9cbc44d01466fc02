"""Clips from MUSCLES' expression libraries (``servoface.sim.expressions``): what ``servoface play <name>`` needs.

- human (an apex pose): onset / apex / offset with minimum-jerk ramps (defaults 0.4 / 1.5 / 0.6 s);
- dog (ordered DFACS events): :func:`~servoface.controller.timeline.dfacs.events_clip` with the given timing
  (default :class:`EventTiming`, released to neutral after the hold unless ``timing`` says otherwise).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from servoface.controller.errors import TimelineError
from servoface.controller.timeline.barker import Expression
from servoface.controller.timeline.clip import ChannelClip
from servoface.controller.timeline.dfacs import EventTiming, events_clip, parse_events
from servoface.controller.timeline.easing import Easing, min_jerk

DEFAULT_ONSET_S = 0.4
DEFAULT_APEX_S = 1.5
DEFAULT_OFFSET_S = 0.6
DEFAULT_DOG_TIMING = EventTiming(release_s=0.8)


def load_expressions(face_type: str | Path) -> dict[str, Any]:
    """The library of a face type (or a head's own library file) as {name: sim.expressions.Expression};
    TimelineError if unavailable."""
    try:
        from servoface.sim.expressions import load_library
    except ImportError as err:  # pragma: no cover - servoface.sim.expressions ships with servoface
        raise TimelineError(f"expression library: servoface.sim.expressions is not available ({err})") from err
    try:
        return dict(load_library(face_type))
    except Exception as err:  # noqa: BLE001 - surface any library error as ours, chained
        raise TimelineError(f"expression library for {face_type!r}: {err}") from err


def library_clip(
    face_type: str,
    name: str,
    *,
    onset_s: float = DEFAULT_ONSET_S,
    apex_s: float = DEFAULT_APEX_S,
    offset_s: float = DEFAULT_OFFSET_S,
    easing: Easing = min_jerk,
    timing: EventTiming | None = None,
    source: str | Path | None = None,
) -> ChannelClip:
    """A playable clip for library expression ``name`` of ``face_type`` (see the module docstring): from the
    library file ``source`` (a head's own, its profile's ``expressions``) where it has the name, else from the
    face type's built-in library (a shipped script's names still play on a head with a library of its own)."""
    library = load_expressions(face_type)
    if source is not None:
        library = {**library, **load_expressions(source)}  # the head's own wins where both have the name
    if name not in library:
        which = (
            f"the {face_type} library"
            if source is None
            else f"the expression library {source} (or the {face_type} one)"
        )
        raise TimelineError(f"expression {name!r} is not in {which}; known: {', '.join(sorted(library))}")
    expr = library[name]
    if face_type == "dog":
        tokens = [{"au": au, "value": value} for au, value in expr.events]
        events = parse_events(tokens, field=f"{face_type}.{name}")
        return events_clip(events, timing or DEFAULT_DOG_TIMING, name=name)
    return Expression.envelope(name, expr.apex(), onset_s, apex_s, offset_s, easing).clip()
