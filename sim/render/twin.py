"""Rendering what the twin sees: a head posed from actuator targets, and target-vs-gated comparisons.

The twin gate and the demo use these: the muscle model's wish (the *target* face) next to the face the
servo goals actually allowed (the *gated* face), posed through ``FaceModel.pose_from_targets``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from servoface.sim.render.images import Image, render_side_by_side
from servoface.sim.render.renderer import HeadRenderer

_MODELS: dict[int, tuple[Any, Any]] = {}  # id(head) -> (head, FaceModel): one model per head, built once


def face_model(head: Any) -> Any:
    """The (cached) `servoface.sim.face_model.FaceModel` of ``head``."""
    known = _MODELS.get(id(head))
    if known is None or known[0] is not head:
        from servoface.sim.face_model import FaceModel

        known = (head, FaceModel(head))
        _MODELS[id(head)] = known
    return known[1]


def render_targets(renderer: HeadRenderer, head: Any, targets: Mapping[str, float], view: str | None = None) -> Image:
    """The head posed straight from actuator targets (role -> deg for joints, mm for skin anchors)."""
    return renderer.render_targets(head, targets, view)


def _render_either(renderer: HeadRenderer, head: Any, what: Mapping[str, float] | Any, view: str | None) -> Image:
    if isinstance(what, Mapping):
        return renderer.render_targets(head, what, view)
    return renderer.render(head, what, view)


def render_target_vs_gated(
    renderer: HeadRenderer,
    head: Any,
    target: Mapping[str, float] | Any,
    gated: Mapping[str, float] | Any,
    labels: Sequence[str] = ("target", "gated"),
    view: str | None = None,
) -> Image:
    """Side by side, labelled: the target face and the gated face.

    Each of ``target`` and ``gated`` is either a `servoface.sim.rig.HeadPose` (e.g. ``FaceModel.solve(aus)``) or a
    mapping of actuator targets (role -> deg / mm), posed through ``FaceModel.pose_from_targets``.
    """
    left = _render_either(renderer, head, target, view)
    right = _render_either(renderer, head, gated, view)
    return render_side_by_side(left, right, labels)
