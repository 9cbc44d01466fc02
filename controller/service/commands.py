"""Validating a command in the submitting thread and building its source (nothing here touches the
loop or the bus: a bad command raises here and changes nothing)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, cast

from servoface.controller.errors import ScriptError
from servoface.controller.frame import FrameValidator
from servoface.controller.inputs.head_ranges import HeadRanges, fit_recording
from servoface.controller.inputs.recorded import Recording
from servoface.controller.service.clock import check_duration_s
from servoface.controller.service.errors import ServiceError
from servoface.controller.service.sources import ClipSource, SamplesSource, Source, Then, transition_clip
from servoface.controller.timeline_on_head import Solve, check_clip_on_head, check_timeline_on_head
from servoface.controller.values import as_finite, printable_repr
from servoface.sim.head import Head

MAX_POINT_MM = 1e6  # a gaze point a kilometre away is a mistake (and far beyond where the gaze changes)


def check_then(then: object) -> Then | None:
    if then is None or (isinstance(then, str) and then in ("hold", "release")):
        return then  # type: ignore[return-value]
    raise ServiceError(
        f"then: expected 'hold' (keep the last pose) or 'release' (empty the track), got {printable_repr(then)}"
    )


def check_point_mm(point_mm: object, *, field: str = "point_mm") -> tuple[float, float, float]:
    """Three finite real numbers (x, y, z) in mm (each within +-1e6), else ServiceError naming ``field``:
    a tuple, a list or a 3-element array; never a string, a mapping or a set."""
    values: tuple[Any, ...] = ()
    if isinstance(point_mm, tuple | list):
        values = tuple(point_mm)
    elif not isinstance(point_mm, str | bytes | Mapping | set | frozenset):
        try:
            values = tuple(point_mm) if len(point_mm) == 3 else ()  # type: ignore[arg-type]  # numpy arrays
        except (TypeError, ValueError):  # not a sized sequence (a bare number, None, a generator)
            values = ()
    numbers_mm = [as_finite(v) for v in values] if len(values) == 3 else []
    if len(numbers_mm) != 3 or any(v is None or abs(v) > MAX_POINT_MM for v in numbers_mm):
        raise ServiceError(f"{field}: expected three finite numbers (x, y, z) in mm, got {printable_repr(point_mm)}")
    x, y, z = (float(v) for v in numbers_mm)  # type: ignore[arg-type]
    return (x, y, z)


def check_intensity(value: object) -> float:
    number = as_finite(value)
    if number is None or not 0 <= number <= 1:
        raise ServiceError(f"intensity: expected a number within 0..1, got {printable_repr(value)}")
    return number


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
    if not isinstance(aus, Mapping):
        raise ServiceError(f"{name}: aus must be a mapping of AU name -> intensity, got {type(aus).__name__}")
    pose = validator.pose(dict(aus), where=name)
    transition = max(check_duration_s(transition_s, field="transition_s"), min_transition_s)
    hold = check_duration_s(hold_s, field="hold_s")
    return ClipSource(transition_clip(pose, transition, hold, merge=merge, name=name), name)


def expression_apex(head: Head, name: object, intensity: object) -> dict[str, float]:
    """A named expression's apex scaled by ``intensity`` (ControllerError naming the unknown name)."""
    from servoface.sim.expressions import load_library

    library = load_library(head.expressions_path or head.face_type)
    if not isinstance(name, str) or name not in library:
        raise ServiceError(f"unknown expression {printable_repr(name)}; known: {sorted(library)}")
    scale = check_intensity(intensity)
    return {au: v * scale for au, v in library[name].apex().items()}


def _on_head(check: Callable[..., None], *args: Any) -> None:
    """Run a `timeline_on_head` check; what the head refuses is a ServiceError (refused at submit)."""
    try:
        check(*args)
    except ScriptError as err:
        raise ServiceError(f"play: {err}") from err


def _check_face(kind: str, what: object, face_type: str, head: Head) -> None:
    theirs = getattr(what, "face_type", None)
    if theirs is not None and theirs != face_type:
        where = getattr(what, "source", None) or kind
        raise ServiceError(f"{kind} {where} is for a {theirs} face; head {head.name!r} is {face_type}")


def play_source(
    head: Head, validator: FrameValidator, what: object, duration_s: object, then: Then | None, solve: Solve
) -> tuple[Source, float | None]:
    """The source for ``play(what)``: a Script (or a script file / shipped script name), a Timeline, a
    Recording, or a timeline Clip. Returns the source and its length (None: a clip's own). ``then`` None:
    a script, timeline or recording holds its last frame, a clip does what its ``holds`` says.

    ``solve``: the head's AU -> targets solver. Every AU a script, timeline or clip plays is solved on it
    first (`timeline_on_head`): what the head refuses (an intensity beyond its own AU table's range) is a
    ServiceError naming the expression and track, nothing placed. A `Recording` (measured input) is held
    inside the head's ranges instead (`inputs.head_ranges`)."""
    timed: Then = then or "hold"
    from servoface.controller.script import Script, load_script
    from servoface.controller.timeline import Timeline

    limit = None if duration_s is None else check_duration_s(duration_s, field="duration_s", allow_zero=False)
    if isinstance(what, str | Path):
        what = load_script(what, library=head.expressions_path)  # the head's own expressions too
    if isinstance(what, Script):
        _check_face("script", what, head.face_type, head)
        _on_head(check_timeline_on_head, what.timeline, solve, str(what.source), head.name)
        end = what.end_s if limit is None else min(what.end_s, limit)
        return SamplesSource(what, end, what.title or Path(what.source).stem, timed), end
    if isinstance(what, Timeline):
        _check_face("timeline", what, head.face_type, head)
        _on_head(check_timeline_on_head, what, solve, "timeline", head.name)
        end = what.end_s if limit is None else min(what.end_s, limit)
        return SamplesSource(what, end, "timeline", timed), end
    if hasattr(what, "duration_s") and hasattr(what, "end_pose") and hasattr(what, "targets"):
        for au, value in what.targets():
            validator.pose({au: value}, where=str(getattr(what, "name", "clip")))
        _on_head(check_clip_on_head, what, solve, head.name)
        from servoface.controller.timeline.clip import Clip

        return ClipSource(cast(Clip, what), then=then), None
    if hasattr(what, "sample") and hasattr(what, "duration_s"):  # a Recording, or a source of the caller's
        _check_face("recording", what, head.face_type, head)
        if isinstance(what, Recording):
            what = fit_recording(what, HeadRanges.of(head))  # a measurement: held inside the head's ranges
        length = float(what.duration_s)
        end = length if limit is None else min(length, limit)
        return SamplesSource(what, end, str(getattr(what, "source", "") or "recording"), timed), end
    raise ServiceError(
        f"play: expected a Script, a script path or shipped name, a Timeline, a Recording or a Clip, got {what!r}"
    )
