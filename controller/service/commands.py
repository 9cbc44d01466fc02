"""Validating a command in the submitting thread and building its source (nothing here touches the
loop or the bus: a bad command raises here and changes nothing)."""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from servoface.controller.frame import FrameValidator
from servoface.controller.service.clock import check_duration_s
from servoface.controller.service.errors import ServiceError
from servoface.controller.service.sources import ClipSource, SamplesSource, Source, Then, transition_clip
from servoface.sim.head import Head


def check_then(then: object) -> Then | None:
    if then is None or then == "hold" or then == "release":
        return then
    raise ServiceError(f"then: expected 'hold' (keep the last pose) or 'release' (empty the track), got {then!r}")


def check_point_mm(point_mm: object, *, field: str = "point_mm") -> tuple[float, float, float]:
    """Three finite real numbers (x, y, z) in mm, else ServiceError naming ``field``."""
    values: tuple[Any, ...]
    try:
        values = tuple(point_mm)  # type: ignore[arg-type]
    except TypeError:
        values = ()
    if len(values) != 3 or not all(
        isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v) for v in values
    ):
        raise ServiceError(f"{field}: expected three finite numbers (x, y, z) in mm, got {point_mm!r}")
    return (float(values[0]), float(values[1]), float(values[2]))


def check_intensity(value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not (0 <= value <= 1):
        raise ServiceError(f"intensity: expected a number within 0..1, got {value!r}")
    return float(value)


def pose_source(
    validator: FrameValidator,
    aus: Mapping[str, Any],
    transition_s: object,
    hold_s: object,
    min_transition_s: float,
    *,
    merge: bool = False,
    name: str = "set_aus",
) -> ClipSource:
    """A validated transition to ``aus`` (see :func:`transition_clip`)."""
    pose = validator.pose(dict(aus) if isinstance(aus, Mapping) else aus, where=name)
    transition = max(check_duration_s(transition_s, field="transition_s"), min_transition_s)
    hold = check_duration_s(hold_s, field="hold_s")
    return ClipSource(transition_clip(pose, transition, hold, merge=merge, name=name), name)


def expression_apex(head: Head, name: object, intensity: object) -> dict[str, float]:
    """A named expression's apex scaled by ``intensity`` (ControllerError naming the unknown name)."""
    from servoface.sim.expressions import load_library

    library = load_library(head.expressions_path or head.face_type)
    if not isinstance(name, str) or name not in library:
        raise ServiceError(f"unknown expression {name!r}; known: {sorted(library)}")
    scale = check_intensity(intensity)
    return {au: v * scale for au, v in library[name].apex().items()}


def _check_face(kind: str, what: object, face_type: str, head: Head) -> None:
    theirs = getattr(what, "face_type", None)
    if theirs is not None and theirs != face_type:
        where = getattr(what, "source", None) or kind
        raise ServiceError(f"{kind} {where} is for a {theirs} face; head {head.name!r} is {face_type}")


def play_source(
    head: Head, validator: FrameValidator, what: object, duration_s: object, then: Then | None
) -> tuple[Source, float | None]:
    """The source for ``play(what)``: a Script (or a script file / shipped script name), a Timeline, a
    Recording, or a timeline Clip. Returns the source and its length (None: a clip's own). ``then`` None:
    a script, timeline or recording holds its last frame, a clip does what its ``holds`` says."""
    timed: Then = then or "hold"
    from servoface.controller.script import Script, load_script
    from servoface.controller.timeline import Timeline

    limit = None if duration_s is None else check_duration_s(duration_s, field="duration_s", allow_zero=False)
    if isinstance(what, str | Path):
        what = load_script(what)
    if isinstance(what, Script):
        _check_face("script", what, head.face_type, head)
        end = what.end_s if limit is None else min(what.end_s, limit)
        return SamplesSource(what, end, what.title or Path(what.source).stem, timed), end
    if isinstance(what, Timeline):
        _check_face("timeline", what, head.face_type, head)
        end = what.end_s if limit is None else min(what.end_s, limit)
        return SamplesSource(what, end, "timeline", timed), end
    if hasattr(what, "duration_s") and hasattr(what, "end_pose") and hasattr(what, "targets"):
        for au, value in what.targets():
            validator.pose({au: value}, where=str(getattr(what, "name", "clip")))
        return ClipSource(what, then=then), None
    if hasattr(what, "sample") and hasattr(what, "duration_s"):  # a Recording
        _check_face("recording", what, head.face_type, head)
        length = float(what.duration_s)
        end = length if limit is None else min(length, limit)
        return SamplesSource(what, end, str(getattr(what, "source", "") or "recording"), timed), end
    raise ServiceError(
        f"play: expected a Script, a script path or shipped name, a Timeline, a Recording or a Clip, got {what!r}"
    )
