"""How the studio frames its twin: the whole head, crown included, with a small margin above it.

`servoface.sim.render.renderer.HeadRenderer` frames a human face as a portrait for stills and clips: its
box is cut off a little above the brows, so the expression fills the picture and the top of the skull is
cut by the image's top edge. The studio's twin is a live view of the head the user drives, so it shows
the whole head: the top of the framed box is raised just enough that the crown, as the camera sees it,
sits `HEADROOM` of the image's height below the top edge. The chin, the sides and the open jaw stay as the
renderer frames them, and the box grows no more than that, so the face stays as large as it can. A head
the renderer already frames whole (the dog) is unchanged.

Imported by the render process only (it pulls in the GL renderer).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.render.camera import default_view, frame_box
from servoface.sim.render.renderer import HeadRenderer

HEADROOM = 0.05  # background above the crown, as a fraction of the image's height
_SEARCH_STEPS = 40


def head_points_mm(head: Any) -> NDArray[np.float64]:
    """(n, 3) float: the points of ``head`` at its neutral pose that make its silhouette: skin vertices
    and the vertices of its parts, not the neck (it hangs below the picture; it never sets the top)."""
    from servoface.sim.kinematics import neutral_pose, part_transforms, posed_skin_vertices

    rest = neutral_pose(head)
    chunks = [np.asarray(posed_skin_vertices(head, rest), dtype=np.float64).reshape(-1, 3)]
    transforms = part_transforms(head, rest.joint_deg)
    for part in head.parts:
        if part.name.startswith("neck"):
            continue
        transform = np.asarray(transforms[part.name], dtype=np.float64)
        vertices = np.asarray(part.mesh.vertices, dtype=np.float64).reshape(-1, 3)
        chunks.append(vertices @ transform[:3, :3].T + transform[:3, 3])
    points = np.concatenate(chunks)
    if not len(points):
        raise ValueError(f"head {getattr(head, 'name', '?')!r} has nothing to frame: no skin and no parts")
    return points


def top_gap(
    points_mm: NDArray[np.float64], lo_mm: NDArray[np.float64], hi_mm: NDArray[np.float64], view: str, aspect: float
) -> float:
    """How far below the image's top edge the highest of ``points_mm`` (n, 3) lands when the camera frames
    the box [lo_mm, hi_mm] from ``view``, as a fraction of the image's height (negative: cut off)."""
    setup = frame_box(lo_mm, hi_mm, view, aspect)
    rotation, eye = setup.pose[:3, :3], setup.pose[:3, 3]
    in_camera = (points_mm - eye) @ rotation  # world -> camera frame (the camera looks along its -z)
    ahead = in_camera[:, 2] < -1e-6
    if not np.any(ahead):
        return -1.0
    ndc_y = in_camera[ahead, 1] / (-in_camera[ahead, 2] * math.tan(setup.yfov_rad / 2.0))
    return float((1.0 - ndc_y.max()) / 2.0)


def whole_head_box(
    points_mm: NDArray[np.float64],
    lo_mm: NDArray[np.float64],
    hi_mm: NDArray[np.float64],
    view: str,
    aspect: float,
    headroom: float = HEADROOM,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The box [lo_mm, hi_mm] with its top raised the least that leaves ``headroom`` (fraction of the
    image's height) above ``points_mm``; returned as it is when it already does."""
    lo, hi = np.asarray(lo_mm, dtype=np.float64).copy(), np.asarray(hi_mm, dtype=np.float64).copy()

    def gap(top_mm: float) -> float:
        raised = hi.copy()
        raised[1] = top_mm
        return top_gap(points_mm, lo, raised, view, aspect)

    if gap(hi[1]) >= headroom:
        return lo, hi
    crown_mm = float(points_mm[:, 1].max())
    below, above = hi[1], max(hi[1], crown_mm)
    step_mm = max(1.0, crown_mm - lo[1])
    for _ in range(_SEARCH_STEPS):  # an upper bound: a top high enough (the margin grows with the box)
        if gap(above) >= headroom:
            break
        below, above = above, above + step_mm
    else:
        return lo, hi
    for _ in range(_SEARCH_STEPS):  # the least top that leaves the headroom: the largest face
        middle = (below + above) / 2.0
        below, above = (below, middle) if gap(middle) >= headroom else (middle, above)
    hi[1] = above
    return lo, hi


class LiveRenderer(HeadRenderer):
    """A `HeadRenderer` that frames the whole head (see the module docstring)."""

    def __init__(self, width: int, height: int, view: str | None = None) -> None:
        super().__init__(width, height, view)
        self._whole: dict[int, tuple[Any, NDArray[np.float64], NDArray[np.float64]]] = {}

    def head_box(self, head: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        key = id(head)
        if key not in self._whole:
            lo, hi = super().head_box(head)
            view = self.view or default_view(str(head.face_type))
            lo, hi = whole_head_box(head_points_mm(head), lo, hi, view, self.width / self.height)
            self._whole[key] = (head, lo, hi)  # the head is kept so its id cannot be reused by another object
        _, lo, hi = self._whole[key]
        return lo, hi
