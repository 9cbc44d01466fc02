"""`HeadRenderer`: one reusable offscreen renderer that draws posed meshes, or a head in a pose.

Create it once and reuse it (an EGL context costs 0.2-0.5 s); use and close it in the thread that made it.
Between frames only what moved is updated: rigid parts move by node pose, the skin's vertex buffer is
rewritten in place (see `servoface.sim.render.scene`).
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from servoface.sim.errors import RenderError
from servoface.sim.render.backend import Offscreen
from servoface.sim.render.camera import CameraSetup, check_view, default_view, frame_box
from servoface.sim.render.scene import MeshItem, MeshScene

Image = NDArray[np.uint8]  # (H, W, 3)
MAX_SIDE_PX = 4096
SKIN_NAME = "skin"


def parse_size(text: str) -> tuple[int, int]:
    """``"640x480"`` -> (640, 480); raises ValueError naming the expected form."""
    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError as err:
        raise ValueError(f"size must look like WIDTHxHEIGHT (e.g. 640x480), got {text!r}") from err
    check_size(width, height)
    return width, height


def check_size(width: int, height: int) -> None:
    if not (16 <= width <= MAX_SIDE_PX and 16 <= height <= MAX_SIDE_PX):
        raise ValueError(f"image size must be 16..{MAX_SIDE_PX} px per side, got {width}x{height}")


def _as_item(item: MeshItem | tuple[Any, ...], index: int) -> MeshItem:
    if isinstance(item, MeshItem):
        return item
    mesh, rgba, *rest = item
    transform = np.asarray(rest[0], dtype=np.float64) if rest else np.eye(4)
    if transform.shape != (4, 4) or not np.all(np.isfinite(transform)):
        raise ValueError(f"mesh {index}: transform must be a finite 4x4 matrix, got shape {transform.shape}")
    return MeshItem(mesh, tuple(rgba), transform, name=str(rest[1]) if len(rest) > 1 else "")


def _box_of(items: Iterable[MeshItem]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for item in items:
        corners = _corners(np.asarray(item.mesh.bounds, dtype=np.float64))
        world = corners @ item.transform[:3, :3].T + item.transform[:3, 3]
        lo, hi = np.minimum(lo, world.min(axis=0)), np.maximum(hi, world.max(axis=0))
    if not np.all(np.isfinite(lo)):
        raise ValueError("nothing to render: no meshes given")
    return lo, hi


def _portrait_crop(
    lo: NDArray[np.float64], hi: NDArray[np.float64], landmarks: Any
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Crop the framed box to the face when the head names its eyes and chin: from a little below the
    chin to well above the brows (a portrait), so the expression, not the crown of the skull, fills the
    image. Heads without those landmarks (the dog: ears matter) are framed whole."""
    try:
        eye_y = (float(landmarks["eye_centre_l"][1]) + float(landmarks["eye_centre_r"][1])) / 2.0
        chin_y = float(landmarks["chin"][1])
    except (KeyError, TypeError, IndexError):
        return lo, hi
    span = eye_y - chin_y
    if span <= 0:
        return lo, hi
    lo, hi = lo.copy(), hi.copy()
    lo[1] = max(lo[1], chin_y - 0.2 * span)
    hi[1] = min(hi[1], eye_y + 0.8 * span)  # issue 11: the face fills the frame (0.3 / 1.1 showed the crown)
    return lo, hi


def _skin_colors(skin: Any) -> NDArray[np.float64] | None:
    colors = getattr(skin, "vertex_colors_rgba", None)
    return None if colors is None else np.asarray(colors)


def _corners(bounds: NDArray[np.float64]) -> NDArray[np.float64]:
    idx = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    return bounds[idx, [0, 1, 2]]


class HeadRenderer:
    """Offscreen renderer of a fixed image size (pixels). ``view``: "front", "three-quarter" or "side";
    None = per head (`servoface.sim.render.camera.default_view`: front for a human face, three-quarter for a dog).

    Raises `servoface.sim.errors.RenderError` if EGL is unavailable (with an install hint) or a frame fails.
    """

    def __init__(self, width: int = 640, height: int = 480, view: str | None = None) -> None:
        check_size(width, height)
        self.width, self.height = width, height
        self.view: str | None = None if view is None else check_view(view)
        self._thread = threading.get_ident()
        self._gl = Offscreen(width, height)
        self._scene = MeshScene(self._gl.pyrender)
        self._framing: tuple[Any, ...] | None = None  # what the camera is framed on (key), to skip redoing it
        self._head_id: int | None = None
        self._head_box: dict[int, tuple[Any, NDArray[np.float64], NDArray[np.float64]]] = {}

    # -- lifecycle ---------------------------------------------------------------------------------
    def close(self) -> None:
        """Free the GL context (same thread that created it). Safe to call twice."""
        if self._gl is not None:
            self._check_thread()
            self._gl.delete()
            self._gl = None  # type: ignore[assignment]

    def __enter__(self) -> HeadRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _check_thread(self) -> None:
        if threading.get_ident() != self._thread:
            raise RenderError("a HeadRenderer must be used and closed in the thread that created it")
        if self._gl is None:
            raise RenderError("this HeadRenderer was closed")

    # -- camera ------------------------------------------------------------------------------------
    def frame(self, lo_mm: ArrayLike, hi_mm: ArrayLike, view: str | None = None) -> CameraSetup:
        """Point the camera at the box [lo_mm, hi_mm] from ``view`` (default: the renderer's view)."""
        view = check_view(view or self.view or "front")
        lo, hi = np.asarray(lo_mm, dtype=np.float64), np.asarray(hi_mm, dtype=np.float64)
        key = (tuple(np.round(lo, 3)), tuple(np.round(hi, 3)), view)
        setup = self._scene.camera
        if self._framing != key or setup is None:
            setup = frame_box(lo, hi, view, self.width / self.height)
            self._scene.set_camera(setup, self.width / self.height)
            self._framing = key
        return setup

    # -- drawing -----------------------------------------------------------------------------------
    def _draw(self, depth: bool) -> tuple[Image, NDArray[np.float32] | None]:
        self._gl.make_current()
        try:
            self._scene.upload()
        finally:
            self._gl.make_uncurrent()
        return self._gl.render(self._scene.scene, depth=depth)

    def render_meshes(
        self,
        items: Sequence[MeshItem | tuple[Any, ...]],
        view: str | None = None,
        box_mm: tuple[ArrayLike, ArrayLike] | None = None,
    ) -> Image:
        """Draw rigid meshes: each item a `MeshItem` or a tuple (trimesh, rgba, transform[, name]).

        The camera frames ``box_mm`` (lo, hi) if given, else the items' bounds. Items are matched to the
        previous call by name (or position): a mesh object seen before is only moved, not re-uploaded.
        """
        return self.render_posed(items, None, view, box_mm)[0]

    def render_posed(
        self,
        items: Sequence[MeshItem | tuple[Any, ...]],
        skin: tuple[Any, ...] | None = None,
        view: str | None = None,
        box_mm: tuple[ArrayLike, ArrayLike] | None = None,
        depth: bool = False,
        face_type: str = "human",
    ) -> tuple[Image, NDArray[np.float32] | None]:
        """Draw rigid ``items`` plus an optional deformable ``skin`` = (vertices (n, 3), faces (m, 3), rgba
        [, vertex colours (n, 4) sRGB 0..1 or None]).

        The skin's buffers are kept between calls while its faces stay the same: only its vertices are
        re-uploaded. Returns the colour image and, if ``depth``, the depth image (mm, 0 = background).
        """
        self._check_thread()
        meshes = [_as_item(it, i) for i, it in enumerate(items)]
        skin_v: NDArray[np.float64] | None = None
        if skin is not None:
            skin_v = np.asarray(skin[0], dtype=np.float64)
            if skin_v.ndim != 2 or skin_v.shape[1] != 3 or not np.all(np.isfinite(skin_v)):
                raise ValueError(f"skin vertices must be finite (n, 3), got shape {skin_v.shape}")
        if box_mm is not None:
            lo, hi = np.asarray(box_mm[0], dtype=np.float64), np.asarray(box_mm[1], dtype=np.float64)
        else:
            boxes = [_box_of(meshes)] if meshes else []
            if skin_v is not None:
                boxes.append((skin_v.min(axis=0), skin_v.max(axis=0)))
            if not boxes:
                raise ValueError("nothing to render: no meshes and no skin given")
            lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
        self.frame(lo, hi, view)
        self._scene.set_rigid(meshes, face_type=face_type)
        if skin is None or skin_v is None:
            self._scene.drop_deformable(keep=set())
        else:
            colors = skin[3] if len(skin) > 3 else None
            self._scene.set_deformable(SKIN_NAME, skin_v, skin[1], tuple(skin[2]), vertex_rgba=colors)
        return self._draw(depth=depth)

    def render_meshes_with_depth(
        self,
        items: Sequence[MeshItem | tuple[Any, ...]],
        view: str | None = None,
        box_mm: tuple[ArrayLike, ArrayLike] | None = None,
    ) -> tuple[Image, NDArray[np.float32]]:
        """Like `render_meshes`, plus depth (H, W) float32 in mm along the camera axis (0 = background)."""
        color, depth = self.render_posed(items, None, view, box_mm, depth=True)
        if depth is None:
            raise RenderError("the renderer returned no depth buffer")
        return color, depth

    # -- heads -------------------------------------------------------------------------------------
    def _draw_head(
        self, head: Any, pose: Any, view: str | None, depth: bool
    ) -> tuple[Image, NDArray[np.float32] | None]:
        from servoface.sim.kinematics import part_transforms, posed_skin_vertices

        self._check_thread()
        if self._head_id != id(head):  # another head: drop the previous head's buffers
            self._scene.set_rigid([])
            self._scene.drop_deformable(keep=set())
            self._head_id = id(head)
        # rest meshes + joint transforms: the GPU keeps each part's mesh, a frame only moves its node
        transforms = part_transforms(head, pose.joint_deg)
        items = [MeshItem(p.mesh, tuple(p.color_rgba), transforms[p.name], p.name) for p in head.parts]
        skin = head.skin
        posed = None  # a mechanical head has no skin: parts only
        if len(skin.vertices_mm) and len(skin.faces):
            posed = (posed_skin_vertices(head, pose), skin.faces, skin.color_rgba, _skin_colors(skin))
        view = view or self.view or default_view(str(head.face_type))
        return self.render_posed(items, posed, view, self.head_box(head), depth=depth, face_type=str(head.face_type))

    def render(self, head: Any, pose: Any, view: str | None = None) -> Image:
        """The head (a `servoface.sim.head.Head`) in ``pose`` (a `servoface.sim.rig.HeadPose`): (H, W, 3) uint8 RGB."""
        return self._draw_head(head, pose, view, depth=False)[0]

    def render_targets(self, head: Any, targets: Mapping[str, float], view: str | None = None) -> Image:
        """The head posed straight from actuator targets (role -> deg / mm) by the twin's face model
        (``FaceModel(head).pose_from_targets``, the model built once per head)."""
        from servoface.sim.render.twin import face_model

        return self.render(head, face_model(head).pose_from_targets(targets), view)

    def render_with_depth(self, head: Any, pose: Any, view: str | None = None) -> tuple[Image, NDArray[np.float32]]:
        """Colour and depth (H, W) float32, mm from the camera along its axis; 0 where only background."""
        color, depth = self._draw_head(head, pose, view, depth=True)
        if depth is None:
            raise RenderError("the renderer returned no depth buffer")
        return color, depth

    def head_box(self, head: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The box the camera frames for ``head``: its skin and parts (not the neck) at the neutral pose and
        with the jaw fully open (so a yawn stays in the picture), cropped to a portrait for a human face."""
        key = id(head)
        if key not in self._head_box:
            from servoface.sim.kinematics import neutral_pose, part_transforms, posed_skin_vertices

            rest = neutral_pose(head)
            poses = [rest]
            jaw = next((j for j in head.joints if j.name == "jaw"), None)
            if jaw is not None:
                poses.append(replace(rest, joint_deg={**rest.joint_deg, "jaw": float(jaw.upper_deg)}))
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            for pose in poses:
                transforms = part_transforms(head, pose.joint_deg)
                items = [
                    MeshItem(p.mesh, tuple(p.color_rgba), transforms[p.name], p.name)
                    for p in head.parts
                    if not p.name.startswith("neck")
                ]
                v = np.asarray(posed_skin_vertices(head, pose))
                if len(v):
                    lo, hi = np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))
                if items:
                    plo, phi = _box_of(items)
                    lo, hi = np.minimum(lo, plo), np.maximum(hi, phi)
            if not np.all(np.isfinite(lo)) and head.parts:  # only neck parts: frame them
                transforms = part_transforms(head, rest.joint_deg)
                lo, hi = _box_of(
                    [MeshItem(p.mesh, tuple(p.color_rgba), transforms[p.name], p.name) for p in head.parts]
                )
            if not np.all(np.isfinite(lo)):
                raise RenderError(f"head {getattr(head, 'name', '?')!r} has nothing to draw: no skin and no parts")
            lo, hi = _portrait_crop(lo, hi, getattr(head, "landmarks_mm", {}))
            # keep the head referenced so its id cannot be reused by another object
            self._head_box[key] = (head, lo, hi)
        _, lo, hi = self._head_box[key]
        return lo, hi
