"""Render looks of the built-in heads (issue 11), rendered for real (EGL on the CPU): closed lids show a
lash line, no dark crease lines below the mouth corners with AU20, teeth show when the lips part, the dog's
head sits on its neck without a gap. Pixels are found by projecting posed landmarks
(`servoface.sim.landmarks`) through the renderer's own camera."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray
from servoface.sim.face_model import FaceModel
from servoface.sim.heads import load_head
from servoface.sim.landmarks import landmark_set
from servoface.sim.render import HeadRenderer
from servoface.sim.render.camera import frame_box

W, H = 480, 480


class Shot:
    """One rendered pose with a projector from head-frame mm to pixel (column, row)."""

    def __init__(self, renderer: HeadRenderer, head: Any, aus: Mapping[str, float], view: str) -> None:
        model = FaceModel(head)
        self.pose = model.solve(aus)
        self.image = renderer.render(head, self.pose, view).astype(np.int64)
        lo, hi = renderer.head_box(head)
        self.camera = frame_box(lo, hi, view, W / H)
        self.landmarks = landmark_set(head)
        self.points = dict(zip(self.landmarks.names, self.landmarks.positions(self.pose), strict=True))

    def pixel(self, p_mm: NDArray[np.float64]) -> tuple[int, int]:
        world_to_cam = np.linalg.inv(self.camera.pose)
        c = world_to_cam[:3, :3] @ np.asarray(p_mm) + world_to_cam[:3, 3]
        t = math.tan(self.camera.yfov_rad / 2.0)
        x_ndc, y_ndc = c[0] / (-c[2] * t * (W / H)), c[1] / (-c[2] * t)
        return int(round((x_ndc + 1.0) / 2.0 * W)), int(round((1.0 - y_ndc) / 2.0 * H))

    def window(self, p_mm: NDArray[np.float64], half_px: int) -> NDArray[np.int64]:
        u, v = self.pixel(p_mm)
        return self.image[max(v - half_px, 0) : v + half_px + 1, max(u - half_px, 0) : u + half_px + 1]


def _luma(pixels: NDArray[np.int64]) -> NDArray[np.float64]:
    return np.asarray(0.299 * pixels[..., 0] + 0.587 * pixels[..., 1] + 0.114 * pixels[..., 2])


def test_projection_lands_on_the_face(renderer: HeadRenderer) -> None:
    shot = Shot(renderer, load_head("human"), {}, "front")
    u_l, v_l = shot.pixel(shot.points["centre_pupil_l"])
    u_r, v_r = shot.pixel(shot.points["centre_pupil_r"])
    assert u_l > u_r and abs(v_l - v_r) <= 1  # the head's left eye is on the image's right
    assert _luma(shot.window(shot.points["centre_pupil_l"], 1)).min() < 40  # a pupil is dark


@pytest.mark.parametrize("au", ["AU43", "AU45"])
def test_closed_lids_show_a_dark_lash_line_and_no_iris(renderer: HeadRenderer, au: str) -> None:
    """A closed lid reads as closed: a dark lash line where the margins meet, no iris showing."""
    shot = Shot(renderer, load_head("human"), {au: 1.0}, "front")
    for side in "lr":
        margin = shot.points[f"margin_upper_lid_{side}"]
        win = shot.window(margin, 4)
        assert _luma(win).min() < 60, "no lash line at the closed lid's margin"
        eye = shot.window(shot.points[f"centre_pupil_{side}"], 8)
        blue = (eye[..., 2] > eye[..., 0] + 25) & (eye[..., 2] > 90)
        assert not blue.any(), "the iris shows through the closed lid"


def test_no_dark_crease_lines_below_the_mouth_corners(renderer: HeadRenderer) -> None:
    """Fear's AU20 + AU26 once uncovered the mouth cavity's rim below the corners: black lines."""
    head = load_head("human")
    shot = Shot(renderer, head, {"AU20": 1.0, "AU26": 0.5, "AU1": 1.0, "AU5": 1.0}, "front")
    for side in "lr":
        corner = shot.points[f"mouth_corner_{side}"]
        for dy_mm in np.arange(3.0, 18.0, 1.5):
            for dx_mm in (-3.0, 0.0, 3.0):
                win = shot.window(corner + np.array([dx_mm * (1 if side == "l" else -1), -dy_mm, 0.0]), 1)
                assert _luma(win).min() > 70, (side, dx_mm, dy_mm)


def test_teeth_show_when_the_lips_part(renderer: HeadRenderer) -> None:
    head = load_head("human")
    closed, open_ = Shot(renderer, head, {}, "front"), Shot(renderer, head, {"AU26": 1.0}, "front")

    def white(shot: Shot) -> int:
        lips = (shot.points["anchor_upper_lip"] + shot.points["anchor_lower_lip"]) / 2.0
        win = shot.window(lips, 30)
        return int(np.count_nonzero(win.min(axis=-1) > 200))

    assert white(closed) == 0 and white(open_) >= 40


def test_the_dog_head_sits_on_its_neck(renderer: HeadRenderer) -> None:
    """No gap between the back of the dog's head and its neck (three-quarter view, head level, down, up):
    along the 40 shortest segments from the neck's mesh to the posed skin, the background shows at
    almost no sample (without the neck collar: 69 of 280)."""
    from scipy.spatial import cKDTree
    from servoface.sim.kinematics import posed_skin_vertices

    head = load_head("dog")
    neck = np.asarray(next(p for p in head.parts if p.name == "neck").mesh.vertices)
    for aus in ({}, {"AU9": 1.0}, {"AU9": -1.0}):
        shot = Shot(renderer, head, aus, "three-quarter")
        background = shot.image[2, 2]
        dist, nearest = cKDTree(posed_skin_vertices(head, shot.pose)).query(neck)
        skin = posed_skin_vertices(head, shot.pose)
        shows = total = 0
        for k in np.argsort(dist)[:40]:
            for t in np.linspace(0.0, 1.0, 7):
                u, v = shot.pixel(neck[k] + t * (skin[nearest[k]] - neck[k]))
                total += 1
                shows += int(np.abs(shot.image[v, u] - background).sum() <= 30)
        assert shows <= 0.02 * total, (aus, shows, total)
