"""Where the camera stands and where the lights are, for a head in the head frame (mm, +y up, +z out of
the face, +x to the head's own left).

The camera frames a fixed box (the head at rest), so an animation never re-frames between frames. Lights
ride with the camera, so every view gets the same key / fill / rim set-up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

View = Literal["front", "three-quarter", "side"]
VIEWS: dict[str, float] = {"front": 0.0, "three-quarter": 35.0, "side": 90.0}  # yaw of the camera, deg
YFOV_DEG = 24.0  # a longish lens: little perspective distortion on a face


@dataclass(frozen=True)
class Light:
    """A directional light in the camera frame: it shines along ``direction`` (unit, camera frame)."""

    name: str
    direction: tuple[float, float, float]
    color: tuple[float, float, float]
    intensity: float


# key from the upper left of the camera, a softer fill from the right, a rim from behind and above.
# The key is the brightest: the fragment shader gives only the brightest light a specular highlight.
LIGHTS: tuple[Light, ...] = (
    Light("key", (0.45, -0.55, -0.70), (1.0, 0.97, 0.92), 3.2),
    Light("fill", (-0.70, -0.15, -0.70), (0.85, 0.90, 1.0), 1.3),
    Light("rim", (0.10, -0.45, 0.89), (1.0, 1.0, 1.0), 2.2),
)
AMBIENT_RGB = (0.16, 0.16, 0.18)
BACKGROUND_RGB = (0.42, 0.45, 0.50)  # neutral grey-blue, darker than skin, lighter than pupils


@dataclass(frozen=True)
class CameraSetup:
    """A camera pose (4x4, camera looks along its own -z, +y up) and its clip planes (mm)."""

    pose: NDArray[np.float64]
    yfov_rad: float
    znear_mm: float
    zfar_mm: float


DEFAULT_VIEWS: dict[str, View] = {"human": "front", "dog": "three-quarter"}  # a dog's snout reads from aside


def default_view(face_type: str) -> View:
    """The view that reads best for a face type: front for a human face, three-quarter for a dog."""
    return DEFAULT_VIEWS.get(face_type, "front")


def check_view(view: str) -> View:
    if view not in VIEWS:
        raise ValueError(f"unknown view {view!r}; expected one of {sorted(VIEWS)}")
    return view  # type: ignore[return-value]


def frame_box(
    lo_mm: NDArray[np.floating],
    hi_mm: NDArray[np.floating],
    view: str = "front",
    aspect: float = 4.0 / 3.0,
    margin: float = 1.12,
) -> CameraSetup:
    """A camera that shows the box [lo_mm, hi_mm] (head frame) whole from ``view``, at image ``aspect``.

    The distance is chosen so the box's bounding sphere projected along the view fits the image.
    """
    yaw = math.radians(VIEWS[check_view(view)])
    lo = np.asarray(lo_mm, dtype=np.float64)
    hi = np.asarray(hi_mm, dtype=np.float64)
    centre = (lo + hi) / 2.0
    half = (hi - lo) / 2.0
    # the box's half extents seen from this yaw: horizontal (x/z mix) and vertical (y)
    half_w = abs(math.cos(yaw)) * half[0] + abs(math.sin(yaw)) * half[2]
    half_h = half[1]
    depth = abs(math.sin(yaw)) * half[0] + abs(math.cos(yaw)) * half[2]
    yfov = math.radians(YFOV_DEG)
    tan_v = math.tan(yfov / 2.0)
    tan_h = tan_v * aspect
    dist = depth + margin * max(half_h / tan_v, half_w / tan_h)
    # a slight downward look (camera a little above) reads a face better than dead level
    elevation = math.radians(6.0)
    direction = np.array(
        [math.sin(yaw) * math.cos(elevation), math.sin(elevation), math.cos(yaw) * math.cos(elevation)]
    )
    eye = centre + dist * direction
    pose = look_at(eye, centre)
    radius = float(np.linalg.norm(half))
    return CameraSetup(pose, yfov, max(1.0, dist - 3.0 * radius), dist + 3.0 * radius)


def look_at(eye: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """Camera-to-world pose at ``eye`` looking at ``target`` with +y up (OpenGL camera convention)."""
    back = eye - target
    back = back / np.linalg.norm(back)
    right = np.cross((0.0, 1.0, 0.0), back)
    right = right / np.linalg.norm(right)
    up = np.cross(back, right)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, up, back, eye
    return pose


def light_pose(camera_pose: NDArray[np.float64], direction_cam: tuple[float, float, float]) -> NDArray[np.float64]:
    """World pose of a directional light (shines along its -z) whose direction is given in camera frame."""
    d_world = camera_pose[:3, :3] @ np.asarray(direction_cam, dtype=np.float64)
    d_world = d_world / np.linalg.norm(d_world)
    return look_at(camera_pose[:3, 3], camera_pose[:3, 3] + d_world)
