"""Rendering what the twin sees: a head posed from actuator targets, and target-vs-gated comparisons.

The twin gate and the demo use these: the muscle model's wish (the *target* face) next to the face the
servo goals actually allowed (the *gated* face), posed through ``FaceModel.pose_from_targets``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from sim.render.images import Image, render_side_by_side
from sim.render.renderer import HeadRenderer

_MODELS: dict[int, tuple[Any, Any]] = {}  # id(head) -> (head, FaceModel): one model per head, built once


def face_model(head: Any) -> Any:
    """The (cached) `sim.face_model.FaceModel` of ``head``."""
    known = _MODELS.get(id(head))
    if known is None or known[0] is not head:
        from sim.face_model import FaceModel

        known = (head, FaceModel(head))
        _MODELS[id(head)] = known
    return known[1]


def render_targets(
    renderer: HeadRenderer, head: Any, targets: Mapping[str, float], view: str | None = None
) -> Image:
    """The head posed straight from actuator targets (role -> deg for joints, mm for skin anchors)."""
    return renderer.render_targets(head, targets, view)


def render_target_vs_gated(
    renderer: HeadRenderer,
    head: Any,
    target: Mapping[str, float] | Any,
    gated_targets: Mapping[str, float],
    labels: Sequence[str] = ("target", "gated"),
    view: str | None = None,
) -> Image:
    """Side by side: the target face (a `HeadPose` or actuator targets) and the gated targets' face."""
    if isinstance(target, Mapping):
        left = render_targets(renderer, head, target, view)
    else:
        left = renderer.render(head, target, view)
    right = render_targets(renderer, head, gated_targets, view)
    return render_side_by_side(left, right, labels)
