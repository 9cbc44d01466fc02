"""Expressions as pictures: an apex still, a neutral -> apex -> neutral clip, a labelled library sheet.

What is drawn by default is the **achievable** face: the muscle model's actuator targets clamped into the
servos' calibrated ranges, gated by the twin, and posed by the twin from the gated goals
(`servoface.sim.achievable.AchievableFace`) — what the head would really do. ``show="target"`` draws the
muscle model's wish instead, ``show="both"`` the two side by side. One reused `HeadRenderer` draws all.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

import numpy as np
from servoface.sim.errors import ExpressionError
from servoface.sim.render.images import Image, contact_sheet, render_side_by_side
from servoface.sim.render.progress import progress
from servoface.sim.render.renderer import HeadRenderer
from servoface.sim.render.twin import face_model
from servoface.sim.render.video import there_and_back

NEUTRAL = "neutral"
SHOWS = ("achievable", "target", "both")
BOTH_LABELS = ("muscle-model target", "what the servos make")


def check_show(show: str) -> str:
    if show not in SHOWS:
        raise ValueError(f"show: expected one of {list(SHOWS)}, got {show!r}")
    return show


def apex_aus(expression: Any) -> dict[str, float]:
    """The apex AU pose of a library expression (``Expression.apex()``), or of a plain AU mapping."""
    if isinstance(expression, Mapping):
        return {str(k): float(v) for k, v in expression.items()}
    apex = getattr(expression, "apex", None)
    if callable(apex):
        apex = apex()
    if not isinstance(apex, Mapping):
        raise ExpressionError(f"expression {getattr(expression, 'name', expression)!r} has no apex AU pose")
    return {str(k): float(v) for k, v in apex.items()}


def pick_expression(library: Mapping[str, Any], name: str) -> dict[str, float]:
    """The apex AUs of ``name`` ("neutral" is always known); the error lists the library's names."""
    if name == NEUTRAL:
        return apex_aus(library[name]) if name in library else {}
    if name not in library:
        names = [NEUTRAL, *sorted(n for n in library if n != NEUTRAL)]
        close = difflib.get_close_matches(name, names, n=1) if isinstance(name, str) else []
        maybe = f" (did you mean {close[0]!r}?)" if close else ""
        raise ExpressionError(f"unknown expression {name!r}{maybe}; this head's library has: {', '.join(names)}")
    return apex_aus(library[name])


_TWINS: dict[int, tuple[Any, Any]] = {}  # id(head) -> (head, AchievableFace): stills need one twin per head


def _achievable(head: Any, achievable: Any) -> Any:
    """The given twin, or the cached one of ``head`` (its gate is built once; `still` resets it)."""
    if achievable is not None:
        return achievable
    known = _TWINS.get(id(head))
    if known is None or known[0] is not head:
        from servoface.sim.achievable import AchievableFace

        known = (head, AchievableFace(head))
        _TWINS[id(head)] = known
    return known[1]


def _draw(renderer: HeadRenderer, head: Any, target: Any, achieved: Any, show: str, view: str | None) -> Image:
    if show == "target":
        return renderer.render(head, target, view)
    right = renderer.render(head, achieved, view)
    if show == "achievable":
        return right
    return render_side_by_side(renderer.render(head, target, view), right, BOTH_LABELS)


def render_aus(
    renderer: HeadRenderer,
    head: Any,
    aus: Mapping[str, float],
    view: str | None = None,
    *,
    show: str = "achievable",
    achievable: Any = None,
) -> Image:
    """The head for ``aus``: the achievable still (default), the muscle-model target, or both."""
    check_show(show)
    target = face_model(head).solve(aus)
    if show == "target":
        return renderer.render(head, target, view)
    achieved = _achievable(head, achievable).still(aus).pose
    return _draw(renderer, head, target, achieved, show, view)


def render_sequence(
    renderer: HeadRenderer,
    head: Any,
    frames: Iterable[Mapping[str, float]],
    view: str | None = None,
    *,
    show: str = "achievable",
    achievable: Any = None,
) -> Iterator[Image]:
    """One image per AU frame of a sequence (a recording sampled at the twin's frame period): the
    achievable face is gated frame after frame, so the servos' rate caps show as lag."""
    check_show(show)
    model = face_model(head)
    twin = None
    if show != "target":
        if achievable is None:
            from servoface.sim.achievable import AchievableFace

            achievable = AchievableFace(head)  # its own: a sequence keeps the gate's state between frames
        twin = achievable
        twin.reset()
    for aus in frames:
        target = model.solve(aus)
        achieved = twin.step(aus).pose if twin is not None else None
        yield _draw(renderer, head, target, achieved, show, view)


def clip_frames(
    renderer: HeadRenderer,
    head: Any,
    aus: Mapping[str, float],
    duration_s: float = 2.0,
    fps: float = 20.0,
    view: str | None = None,
    show_progress: bool | None = None,
    *,
    show: str = "achievable",
    achievable: Any = None,
) -> Iterator[Image]:
    """Frames of neutral -> apex -> neutral (smooth easing); AU intensities scale with the easing weight.
    The achievable face is gated frame after frame at ``fps`` (the servos' rate caps show as lag)."""
    check_show(show)
    model = face_model(head)
    weights = there_and_back(duration_s, fps)
    twin = None
    if show != "target":
        if achievable is None:
            from servoface.sim.achievable import AchievableFace

            achievable = AchievableFace(head, frame_period_s=1.0 / fps)
        twin = achievable
        twin.reset()
    for w in progress(weights, total=len(weights), desc="frames", enabled=show_progress):
        frame = {k: float(w) * v for k, v in aus.items()}
        target = model.solve(frame)
        achieved = twin.step(frame).pose if twin is not None else None
        yield _draw(renderer, head, target, achieved, show, view)


def library_sheet(
    renderer: HeadRenderer,
    head: Any,
    library: Mapping[str, Any],
    columns: int | None = None,
    view: str | None = None,
    show_progress: bool | None = None,
    *,
    show: str = "achievable",
    achievable: Any = None,
) -> tuple[Image, list[str]]:
    """A labelled contact sheet of every expression at its apex, neutral first; returns it and the labels.
    With ``show="both"`` each cell is the target and the achievable face side by side."""
    check_show(show)
    twin = None if show == "target" else _achievable(head, achievable)
    names = [NEUTRAL, *[n for n in library if n != NEUTRAL]]
    images = [
        render_aus(renderer, head, pick_expression(library, name), view, show=show, achievable=twin)
        for name in progress(names, total=len(names), desc="expressions", enabled=show_progress)
    ]
    if columns is None:
        columns = int(np.ceil(np.sqrt(len(images) * (0.6 if show == "both" else 1.2))))
    return contact_sheet(images, names, columns), names
