"""The built-in heads rendered for real (EGL, small sizes): faces read, expressions are distinct."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest
from servoface.sim.render import HeadRenderer
from servoface.sim.render.camera import BACKGROUND_RGB, default_view
from servoface.sim.render.clips import library_sheet, pick_expression, render_aus
from servoface.sim.render.twin import face_model, render_target_vs_gated, render_targets

W, H = 160, 120
# mean absolute difference (0..255 per channel) over the face region that two expressions must exceed.
# Measured at 160x120 (default views): the closest human pairs are neutral/blink/wink (~1.0, the eyes
# only), the closest dog pair anger/anger_without_tongue (~1.1, the tongue only); most pairs are > 2.
MIN_PAIR_DIFF = 0.8


@pytest.fixture(scope="module")
def heads() -> dict[str, Any]:
    from servoface.sim.heads import load_head

    return {name: load_head(name) for name in ("human", "dog")}


def _background_mask(img: np.ndarray) -> np.ndarray:
    bg = np.round(np.array(BACKGROUND_RGB) * 255)
    return np.abs(img.astype(int) - bg).sum(axis=2) <= 6


@pytest.mark.parametrize("name", ["human", "dog"])
def test_neutral_face_fills_the_frame_in_skin_colour_with_dark_eyes(
    renderer: HeadRenderer, heads: dict[str, Any], name: str
) -> None:
    from servoface.sim.kinematics import neutral_pose

    head = heads[name]
    img = renderer.render(head, neutral_pose(head))
    face = ~_background_mask(img)
    assert 0.15 < face.mean() < 0.95  # framed: the head fills much of the image, not all of it
    assert _background_mask(img)[0].mean() > 0.5  # background along the top edge
    pixels = img[face].astype(int)
    warm = (pixels[:, 0] > pixels[:, 2] + 10).mean()
    assert warm > 0.5  # mostly skin/fur colour (red over blue)
    dark = (pixels.sum(axis=1) < 120).sum()
    assert dark >= 4  # pupils (and other dark features) are visible


@pytest.mark.parametrize("name", ["human", "dog"])
def test_depth_is_nearer_at_the_face_than_the_background(
    renderer: HeadRenderer, heads: dict[str, Any], name: str
) -> None:
    from servoface.sim.kinematics import neutral_pose

    head = heads[name]
    color, depth = renderer.render_with_depth(head, neutral_pose(head))
    assert depth.shape == (H, W)
    bg = _background_mask(color)
    assert np.all(depth[bg & (depth > 0)] >= 0)  # nothing behind the camera
    assert (depth[~bg] > 0).mean() > 0.98  # every face pixel has a depth
    lo, hi = renderer.head_box(head)
    cam = renderer.frame(lo, hi, default_view(head.face_type))  # the view render() used for this head
    dist = np.linalg.norm(cam.pose[:3, 3] - (lo + hi) / 2)
    radius = np.linalg.norm(hi - lo) / 2
    near = depth[depth > 0]
    assert dist - radius - 1 <= near.min() <= dist  # the nearest point is the face, inside the framed box


def _diff(a: np.ndarray, b: np.ndarray, region: np.ndarray) -> float:
    return float(np.abs(a.astype(int) - b)[region].mean())


@pytest.mark.parametrize("name", ["human", "dog"])
def test_every_expression_is_visibly_different_from_neutral_and_the_others(
    renderer: HeadRenderer, heads: dict[str, Any], name: str
) -> None:
    from servoface.sim.expressions import load_library

    head = heads[name]
    library = load_library(head.face_type)
    names = ["neutral", *[n for n in library if n != "neutral"]]
    assert len(names) >= 5
    view = default_view(head.face_type)
    images = {n: render_aus(renderer, head, pick_expression(library, n), view) for n in names}
    region = np.zeros((H, W), bool)
    for img in images.values():
        region |= ~_background_mask(img)
    too_close = [
        (a, b, round(_diff(images[a], images[b], region), 2))
        for a, b in itertools.combinations(names, 2)
        if _diff(images[a], images[b], region) <= MIN_PAIR_DIFF
    ]
    assert not too_close, f"{name}: expressions too alike (mean abs diff over the face <= {MIN_PAIR_DIFF})"


def test_library_sheet_puts_neutral_first_and_labels_every_cell(renderer: HeadRenderer, heads: dict[str, Any]) -> None:
    from servoface.sim.expressions import load_library

    library = load_library("human")
    sheet, names = library_sheet(renderer, heads["human"], library, columns=5)
    assert names[0] == "neutral" and len(names) == len({"neutral", *library})
    rows = -(-len(names) // 5)
    assert sheet.shape[1] == 5 * W + 6 * 4 and sheet.shape[0] > rows * H


def test_render_targets_and_side_by_side(renderer: HeadRenderer, heads: dict[str, Any]) -> None:
    head = heads["human"]
    model = face_model(head)
    neutral_targets = model.solve({}).actuator_targets
    open_jaw = dict(neutral_targets, jaw=20.0)
    neutral_img = render_targets(renderer, head, neutral_targets)
    open_img = render_targets(renderer, head, open_jaw)
    changed = np.abs(neutral_img.astype(int) - open_img).sum(axis=2) > 20
    ys = np.nonzero(changed)[0]
    assert len(ys) > 20 and ys.mean() > H * 0.5  # the jaw opened: change in the lower half
    both = render_target_vs_gated(renderer, head, open_jaw, neutral_targets)
    assert both.shape[1] == 2 * W + 3 * 4
    assert np.array_equal(both[4 : 4 + H, 4 : 4 + W], open_img)
    assert np.array_equal(both[4 : 4 + H, 8 + W : 8 + 2 * W], neutral_img)
