"""A persistent pyrender scene whose meshes are updated in place between frames.

Rigid meshes become GPU buffers once and then only move (node poses). A deformable mesh (the skin) keeps
its buffers too: each frame its positions and normals are written into the existing vertex buffer with
``glBufferSubData`` instead of building a new pyrender mesh. The skin is drawn twice from one position
array: outside in its own colour, and the inside (reversed winding) in a dark mouth-cavity colour, so an
open mouth shows a dark cavity instead of the background.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim.render.camera import AMBIENT_RGB, BACKGROUND_RGB, LIGHTS, CameraSetup, light_pose
from sim.render.materials import (
    MOUTH_CAVITY_RGBA,
    eye_vertex_colors,
    finish_for,
    srgb_to_linear,
    srgb_to_linear_array,
)
from sim.render.normals import VertexNormals

Transform = NDArray[np.float64]  # (4, 4)


@dataclass(frozen=True)
class MeshItem:
    """One rigid mesh to draw: a trimesh (any frame), its sRGB colour and its 4x4 pose in the world."""

    mesh: Any
    color_rgba: tuple[float, float, float, float]
    transform: Transform = field(default_factory=lambda: np.eye(4))
    name: str = ""


def _material(
    pyrender: Any, name: str, rgba: Sequence[float], vertex_colored: bool = False, double_sided: bool = False
) -> Any:
    finish = finish_for(name)
    base = np.ones(4) if vertex_colored else srgb_to_linear(tuple(rgba))
    return pyrender.MetallicRoughnessMaterial(
        baseColorFactor=base,
        metallicFactor=finish.metallic,
        roughnessFactor=finish.roughness,
        alphaMode="BLEND" if base[3] < 1.0 else "OPAQUE",
        doubleSided=double_sided,
    )


class _Deformable:
    """The skin: one pyrender mesh with an outside and an inside primitive sharing positions.

    ``vertex_rgba``: optional (n, 4) sRGB colours per vertex (lips, brows) on the outside.
    The interleaved vertex buffers (position, normal[, colour]) are kept host-side too, so a frame only
    rewrites the position and normal columns and uploads the whole buffer in one call.
    """

    def __init__(
        self,
        pyrender: Any,
        name: str,
        faces: NDArray[np.integer],
        n_vertices: int,
        rgba: Any,
        vertex_rgba: NDArray[np.floating] | None = None,
    ) -> None:
        self.source_faces = faces
        self.source_colors = vertex_rgba
        self.faces = np.ascontiguousarray(faces, dtype=np.uint32)
        self.normals = VertexNormals(self.faces, n_vertices)
        zeros = np.zeros((n_vertices, 3), dtype=np.float32)
        up = np.tile(np.float32([0, 0, 1]), (n_vertices, 1))
        colors = None
        if vertex_rgba is not None:
            c = np.asarray(vertex_rgba, dtype=np.float64)
            if c.shape != (n_vertices, 4) or not np.all(np.isfinite(c)) or c.min() < 0 or c.max() > 1:
                raise ValueError(f"skin vertex colours must be ({n_vertices}, 4) in 0..1, got {c.shape}")
            colors = srgb_to_linear_array(c)
        self.outside = pyrender.Primitive(
            positions=zeros,
            normals=up,
            color_0=colors,
            indices=self.faces,
            material=_material(pyrender, name, rgba, vertex_colored=colors is not None),
        )
        self.inside = pyrender.Primitive(
            positions=zeros,
            normals=-up,
            indices=self.faces[:, ::-1].copy(),
            material=_material(pyrender, "cavity", MOUTH_CAVITY_RGBA),
        )
        self.mesh = pyrender.Mesh([self.outside, self.inside], name=name)
        self._out_buf = np.zeros((n_vertices, 6 if colors is None else 10), dtype=np.float32)
        if colors is not None:
            self._out_buf[:, 6:] = colors
        self._in_buf = np.zeros((n_vertices, 6), dtype=np.float32)
        self._pending = False

    def set_vertices(self, vertices: NDArray[np.floating]) -> None:
        v = np.asarray(vertices, dtype=np.float32)
        n = self.normals(v)
        self.outside.positions = v
        self.outside.normals = n
        self.inside.positions = v
        self.inside.normals = -n
        self._out_buf[:, :3] = v
        self._out_buf[:, 3:6] = n
        self._in_buf[:, :3] = v
        self._in_buf[:, 3:6] = -n
        self._pending = True

    def upload(self) -> None:
        """Write pending vertices into the GL buffers (context must be current)."""
        if not self._pending:
            return
        from OpenGL import GL

        for prim, data in ((self.outside, self._out_buf), (self.inside, self._in_buf)):
            if not prim._in_context():  # not drawn yet: pyrender uploads positions/normals itself
                continue
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, prim._buffers[0])
            GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, data.nbytes, data)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        self._pending = False


def _same_topology(
    buffers: _Deformable, faces: NDArray[np.integer], n_vertices: int, colors: NDArray[np.floating] | None
) -> bool:
    if n_vertices != buffers.normals.n_vertices or (colors is None) != (buffers.source_colors is None):
        return False
    if colors is not None and colors is not buffers.source_colors:
        if not np.array_equal(colors, np.asarray(buffers.source_colors)):
            return False
    return buffers.source_faces is faces or bool(np.array_equal(buffers.faces, faces))


class MeshScene:
    """The scene: background, ambient light, camera, camera-fixed key/fill/rim lights, meshes by name."""

    def __init__(self, pyrender: Any) -> None:
        self.pyrender = pyrender
        self.scene = pyrender.Scene(bg_color=(*BACKGROUND_RGB, 1.0), ambient_light=AMBIENT_RGB)
        self._camera_node: Any = None
        self._light_nodes: list[tuple[Any, tuple[float, float, float]]] = []
        self._rigid: dict[str, tuple[Any, Any]] = {}  # name -> (source trimesh, node)
        self._deformable: dict[str, tuple[_Deformable, Any]] = {}  # name -> (buffers, node)
        for light in LIGHTS:
            node = self.scene.add(
                pyrender.DirectionalLight(color=light.color, intensity=light.intensity),
                name=f"light_{light.name}",
                pose=np.eye(4),
            )
            self._light_nodes.append((node, light.direction))
        self.camera: CameraSetup | None = None

    def set_camera(self, setup: CameraSetup, aspect: float) -> None:
        cam = self.pyrender.PerspectiveCamera(
            yfov=setup.yfov_rad, znear=setup.znear_mm, zfar=setup.zfar_mm, aspectRatio=aspect
        )
        if self._camera_node is not None:
            self.scene.remove_node(self._camera_node)
        self._camera_node = self.scene.add(cam, name="camera", pose=setup.pose)
        for node, direction in self._light_nodes:
            self.scene.set_pose(node, light_pose(setup.pose, direction))
        self.camera = setup

    def set_rigid(self, items: Sequence[MeshItem], face_type: str = "human") -> None:
        """Show exactly ``items`` (by name, else list index): add new ones, move known ones.

        Eyeballs (parts named ``eyeball*`` without vertex colours) get a painted iris and pupil unless
        the items carry their own iris or pupil parts.
        """
        paint_eyes = not any(("iris" in it.name or "pupil" in it.name) for it in items)
        wanted: set[str] = set()
        for i, item in enumerate(items):
            name = item.name or f"mesh{i}"
            wanted.add(name)
            known = self._rigid.get(name)
            if known is None or known[0] is not item.mesh:
                if known is not None:
                    self.scene.remove_node(known[1])
                mesh = self._rigid_mesh(item, name, face_type, paint_eyes)
                node = self.scene.add(mesh, name=name, pose=item.transform)
                self._rigid[name] = (item.mesh, node)
            else:
                self.scene.set_pose(known[1], np.asarray(item.transform, dtype=np.float64))
        for name in [n for n in self._rigid if n not in wanted]:
            self.scene.remove_node(self._rigid.pop(name)[1])

    def _rigid_mesh(self, item: MeshItem, name: str, face_type: str, paint_eyes: bool) -> Any:
        pr = self.pyrender
        mesh = item.mesh
        colors = None
        if getattr(mesh.visual, "kind", None) == "vertex":
            colors = srgb_to_linear_array(np.asarray(mesh.visual.vertex_colors, dtype=np.float64) / 255.0)
        elif paint_eyes and name.startswith("eyeball"):
            if len(mesh.vertices) < 2000:  # fine enough that the iris and pupil are round
                mesh = mesh.subdivide().subdivide() if len(mesh.vertices) < 600 else mesh.subdivide()
            colors = eye_vertex_colors(mesh.vertices, face_type)
        if colors is None:
            shaded = mesh.smooth_shaded  # splits vertices at sharp edges: boxes stay boxy, spheres smooth
            positions, normals, faces = shaded.vertices, shaded.vertex_normals, shaded.faces
        else:
            positions, normals, faces = mesh.vertices, mesh.vertex_normals, mesh.faces
        prim = pr.Primitive(
            positions=np.asarray(positions, dtype=np.float32),
            normals=np.asarray(normals, dtype=np.float32),
            indices=np.asarray(faces, dtype=np.uint32),
            color_0=colors,
            # an open mesh (an iris disc, an ear flap) is drawn from both sides, whatever its winding
            material=_material(
                pr,
                name,
                item.color_rgba,
                vertex_colored=colors is not None,
                double_sided=not mesh.is_watertight,
            ),
        )
        return pr.Mesh([prim], name=name)

    def set_deformable(
        self,
        name: str,
        vertices: NDArray[np.floating],
        faces: NDArray[np.integer],
        rgba: Any,
        pose: Transform | None = None,
        vertex_rgba: NDArray[np.floating] | None = None,
    ) -> None:
        """Show a mesh whose vertices change every frame; same ``faces`` array = buffers are reused."""
        known = self._deformable.get(name)
        if known is None or not _same_topology(known[0], faces, len(vertices), vertex_rgba):
            if known is not None:
                self.scene.remove_node(known[1])
            buffers = _Deformable(self.pyrender, name, faces, len(vertices), rgba, vertex_rgba)
            node = self.scene.add(buffers.mesh, name=name, pose=np.eye(4) if pose is None else pose)
            known = (buffers, node)
            self._deformable[name] = known
        elif pose is not None:
            self.scene.set_pose(known[1], pose)
        known[0].set_vertices(vertices)

    def drop_deformable(self, keep: set[str]) -> None:
        for name in [n for n in self._deformable if n not in keep]:
            self.scene.remove_node(self._deformable.pop(name)[1])

    def upload(self) -> None:
        """Push changed vertex data to the GPU; call with the GL context current, right before drawing."""
        for buffers, _ in self._deformable.values():
            buffers.upload()
