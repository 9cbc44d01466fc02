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
from sim.render.materials import MOUTH_CAVITY_RGBA, eye_vertex_colors, finish_for, srgb_to_linear
from sim.render.normals import VertexNormals

Transform = NDArray[np.float64]  # (4, 4)


@dataclass(frozen=True)
class MeshItem:
    """One rigid mesh to draw: a trimesh (any frame), its sRGB colour and its 4x4 pose in the world."""

    mesh: Any
    color_rgba: tuple[float, float, float, float]
    transform: Transform = field(default_factory=lambda: np.eye(4))
    name: str = ""


def _material(pyrender: Any, name: str, rgba: Sequence[float], vertex_colored: bool = False) -> Any:
    finish = finish_for(name)
    base = np.ones(4) if vertex_colored else srgb_to_linear(tuple(rgba))
    return pyrender.MetallicRoughnessMaterial(
        baseColorFactor=base,
        metallicFactor=finish.metallic,
        roughnessFactor=finish.roughness,
        alphaMode="BLEND" if base[3] < 1.0 else "OPAQUE",
    )


class _Deformable:
    """The skin: one pyrender mesh with an outside and an inside primitive sharing positions."""

    def __init__(
        self, pyrender: Any, name: str, faces: NDArray[np.integer], n_vertices: int, rgba: Any
    ) -> None:
        self.source_faces = faces
        self.faces = np.ascontiguousarray(faces, dtype=np.uint32)
        self.normals = VertexNormals(self.faces, n_vertices)
        zeros = np.zeros((n_vertices, 3), dtype=np.float32)
        up = np.tile(np.float32([0, 0, 1]), (n_vertices, 1))
        self.outside = pyrender.Primitive(
            positions=zeros, normals=up, indices=self.faces, material=_material(pyrender, name, rgba)
        )
        self.inside = pyrender.Primitive(
            positions=zeros,
            normals=-up,
            indices=self.faces[:, ::-1].copy(),
            material=_material(pyrender, "cavity", MOUTH_CAVITY_RGBA),
        )
        self.mesh = pyrender.Mesh([self.outside, self.inside], name=name)
        self._pending: NDArray[np.float32] | None = None

    def set_vertices(self, vertices: NDArray[np.floating]) -> None:
        v = np.asarray(vertices, dtype=np.float32)
        n = self.normals(v)
        self.outside.positions = v
        self.outside.normals = n
        self.inside.positions = v
        self.inside.normals = -n
        self._pending = np.ascontiguousarray(np.hstack([v, n]))

    def upload(self) -> None:
        """Write pending vertices into the GL buffers (context must be current)."""
        if self._pending is None:
            return
        from OpenGL import GL

        for prim, data in ((self.outside, self._pending), (self.inside, None)):
            if not prim._in_context():  # not drawn yet: pyrender uploads positions/normals itself
                continue
            if data is None:
                data = self._pending.copy()
                data[:, 3:] *= -1.0
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, prim._buffers[0])
            GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, data.nbytes, data)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        self._pending = None


def _same_topology(buffers: _Deformable, faces: NDArray[np.integer], n_vertices: int) -> bool:
    if n_vertices != buffers.normals.n_vertices:
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
        """Show exactly ``items`` (by name, else list index): add new ones, move known ones."""
        wanted: set[str] = set()
        for i, item in enumerate(items):
            name = item.name or f"mesh{i}"
            wanted.add(name)
            known = self._rigid.get(name)
            if known is None or known[0] is not item.mesh:
                if known is not None:
                    self.scene.remove_node(known[1])
                node = self.scene.add(self._rigid_mesh(item, name, face_type), name=name, pose=item.transform)
                self._rigid[name] = (item.mesh, node)
            else:
                self.scene.set_pose(known[1], np.asarray(item.transform, dtype=np.float64))
        for name in [n for n in self._rigid if n not in wanted]:
            self.scene.remove_node(self._rigid.pop(name)[1])

    def _rigid_mesh(self, item: MeshItem, name: str, face_type: str) -> Any:
        pr = self.pyrender
        mesh = item.mesh
        colors = None
        if getattr(mesh.visual, "kind", None) == "vertex":
            colors = np.asarray(mesh.visual.vertex_colors, dtype=np.float64) / 255.0
            colors = np.array([srgb_to_linear(tuple(c)) for c in colors], dtype=np.float32)
        elif name.startswith("eyeball"):
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
            material=_material(pr, name, item.color_rgba, vertex_colored=colors is not None),
        )
        return pr.Mesh([prim], name=name)

    def set_deformable(
        self,
        name: str,
        vertices: NDArray[np.floating],
        faces: NDArray[np.integer],
        rgba: Any,
        pose: Transform | None = None,
    ) -> None:
        """Show a mesh whose vertices change every frame; same ``faces`` array = buffers are reused."""
        known = self._deformable.get(name)
        if known is None or not _same_topology(known[0], faces, len(vertices)):
            if known is not None:
                self.scene.remove_node(known[1])
            buffers = _Deformable(self.pyrender, name, faces, len(vertices), rgba)
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
