"""Expressions as pictures: an apex still, a neutral -> apex -> neutral clip, a labelled library sheet.

Everything goes through the face model (``FaceModel.solve``) and one reused `HeadRenderer`, so what is
drawn is exactly the pose the controller would command.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
from servoface.sim.errors import ExpressionError
from servoface.sim.render.images import Image, contact_sheet
from servoface.sim.render.progress import progress
from servoface.sim.render.renderer import HeadRenderer
from servoface.sim.render.twin import face_model
from servoface.sim.render.video import there_and_back

NEUTRAL = "neutral"


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
        known = ", ".join([NEUTRAL, *sorted(n for n in library if n != NEUTRAL)])
        raise ExpressionError(f"unknown expression {name!r}; this head's library has: {known}")
    return apex_aus(library[name])


def render_aus(renderer: HeadRenderer, head: Any, aus: Mapping[str, float], view: str | None = None) -> Image:
    """The head with the face model solved for ``aus``."""
    return renderer.render(head, face_model(head).solve(aus), view)


def clip_frames(
    renderer: HeadRenderer,
    head: Any,
    aus: Mapping[str, float],
    duration_s: float = 2.0,
    fps: float = 20.0,
    view: str | None = None,
    show_progress: bool | None = None,
) -> Iterator[Image]:
    """Frames of neutral -> apex -> neutral (smooth easing); AU intensities scale with the easing weight."""
    model = face_model(head)
    weights = there_and_back(duration_s, fps)
    for w in progress(weights, total=len(weights), desc="frames", enabled=show_progress):
        yield renderer.render(head, model.solve({k: float(w) * v for k, v in aus.items()}), view)


def library_sheet(
    renderer: HeadRenderer,
    head: Any,
    library: Mapping[str, Any],
    columns: int | None = None,
    view: str | None = None,
    show_progress: bool | None = None,
) -> tuple[Image, list[str]]:
    """A labelled contact sheet of every expression at its apex, neutral first; returns it and the labels."""
    names = [NEUTRAL, *[n for n in library if n != NEUTRAL]]
    images = [
        render_aus(renderer, head, pick_expression(library, name), view)
        for name in progress(names, total=len(names), desc="expressions", enabled=show_progress)
    ]
    if columns is None:
        columns = int(np.ceil(np.sqrt(len(images) * 1.2)))
    return contact_sheet(images, names, columns), names
