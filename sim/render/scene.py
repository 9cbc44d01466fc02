"""A persistent pyrender scene whose meshes are updated in place between frames.

Rigid parts are batched by finish into a few primitives moved on the CPU; the skin (deformable) keeps its
buffers too. Each frame only rewrites vertex buffers in place (`servoface.sim.render.buffers`) instead of building
new pyrender meshes. The skin is drawn twice from one position array: outside in its own colour, and the
inside (reversed winding) in a dark mouth-cavity colour, so an open mouth shows a dark cavity instead of
the background.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.render.buffers import DynamicPrimitive, PartGeometry, RigidBatch
from servoface.sim.render.camera import AMBIENT_RGB, BACKGROUND_RGB, LIGHTS, CameraSetup, light_pose
from servoface.sim.render.materials import (
    MOUTH_CAVITY_RGBA,
    eye_vertex_colors,
    finish_for,
    srgb_to_linear,
    srgb_to_linear_array,
)
from servoface.sim.render.normals import VertexNormals

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
    """A pyrender material for a surface named ``name`` (finish by name, colour linearised)."""
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
        colors = None
        if vertex_rgba is not None:
            c = np.asarray(vertex_rgba, dtype=np.float64)
            if c.shape != (n_vertices, 4) or not np.all(np.isfinite(c)) or c.min() < 0 or c.max() > 1:
                raise ValueError(f"skin vertex colours must be ({n_vertices}, 4) in 0..1, got {c.shape}")
            colors = srgb_to_linear_array(c)
        outside_material = _material(pyrender, name, rgba, vertex_colored=colors is not None)
        self.outside = DynamicPrimitive(pyrender, self.faces, n_vertices, outside_material, colors)
        inside_material = _material(pyrender, "cavity", MOUTH_CAVITY_RGBA)
        self.inside = DynamicPrimitive(pyrender, self.faces[:, ::-1], n_vertices, inside_material)
        self.mesh = pyrender.Mesh([self.outside.prim, self.inside.prim], name=name)
        self.mesh.draw_order = -1  # drawn first: it hides most of the rigid parts (early depth test)

    def set_vertices(self, vertices: NDArray[np.floating]) -> None:
        v = np.asarray(vertices, dtype=np.float32)
        n = self.normals(v)
        self.outside.set(v, n)
        self.inside.set(v, -n)

    def upload(self) -> None:
        """Write pending vertices into the GL buffers (context must be current)."""
        self.outside.upload()
        self.inside.upload()


def _same_topology(
    buffers: _Deformable, faces: NDArray[np.integer], n_vertices: int, colors: NDArray[np.floating] | None
) -> bool:
    if n_vertices != buffers.normals.n_vertices or (colors is None) != (buffers.source_colors is None):
        return False
    if colors is not None and colors is not buffers.source_colors:
        if not np.array_equal(colors, np.asarray(buffers.source_colors)):
            return False
    return buffers.source_faces is faces or bool(np.array_equal(buffers.faces, faces))


def part_geometry(item: MeshItem, name: str, face_type: str, paint_eyes: bool) -> PartGeometry:
    """A rigid part's rest geometry with per-vertex linear colours (its colour, own vertex colours, or a
    painted eye), smooth normals split at sharp edges (a box stays boxy, a sphere smooth)."""
    mesh = item.mesh
    colors: NDArray[np.float32] | None = None
    if getattr(mesh.visual, "kind", None) == "vertex":
        colors = srgb_to_linear_array(np.asarray(mesh.visual.vertex_colors, dtype=np.float64) / 255.0)
    elif paint_eyes and name.startswith("eyeball"):
        if len(mesh.vertices) < 2000:  # fine enough that the iris and pupil are round
            mesh = mesh.subdivide().subdivide() if len(mesh.vertices) < 600 else mesh.subdivide()
        colors = eye_vertex_colors(mesh.vertices, face_type)
    if colors is None:
        shaded = mesh.smooth_shaded
        positions, normals, faces = shaded.vertices, shaded.vertex_normals, shaded.faces
        colors = np.tile(srgb_to_linear(tuple(item.color_rgba)).astype(np.float32), (len(positions), 1))
    else:
        positions, normals, faces = mesh.vertices, mesh.vertex_normals, mesh.faces
    return PartGeometry(
        name,
        np.asarray(positions, dtype=np.float64),
        np.asarray(normals, dtype=np.float64),
        np.asarray(faces, dtype=np.int64),
        colors,
    )


class MeshScene:
    """The scene: background, ambient light, camera, camera-fixed key/fill/rim lights, meshes by name."""

    def __init__(self, pyrender: Any) -> None:
        self.pyrender = pyrender
        self.scene = pyrender.Scene(bg_color=(*BACKGROUND_RGB, 1.0), ambient_light=AMBIENT_RGB)
        self._camera_node: Any = None
        self._light_nodes: list[tuple[Any, tuple[float, float, float]]] = []
        self._rigid_signature: tuple[tuple[str, int], ...] | None = None
        self._rigid_meshes: list[Any] = []
        self._batches: list[tuple[RigidBatch, list[int]]] = []  # batch, indices of its parts in the items
        self._batch_nodes: dict[int, Any] = {}
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
        """Show exactly ``items`` (by name, else list index). The same parts as last time only move.

        Parts are batched by surface finish (see `servoface.sim.render.buffers`). Eyeballs (parts named
        ``eyeball*`` without vertex colours) get a painted iris and pupil unless the items carry their own
        iris or pupil parts. Open meshes (an iris disc, an ear flap) are drawn from both sides.
        """
        names = [it.name or f"mesh{i}" for i, it in enumerate(items)]
        signature = tuple((n, id(it.mesh)) for n, it in zip(names, items, strict=True))
        if signature != self._rigid_signature:
            self._build_batches(items, names, face_type)
            self._rigid_signature = signature
            self._rigid_meshes = [it.mesh for it in items]  # keep them alive: ids stay unique
        transforms = [np.asarray(it.transform, dtype=np.float64) for it in items]
        for batch, indices in self._batches:
            batch.set_transforms([transforms[i] for i in indices])

    def _build_batches(self, items: Sequence[MeshItem], names: list[str], face_type: str) -> None:
        for batch, _ in self._batches:
            self.scene.remove_node(self._batch_nodes.pop(id(batch)))
        self._batches = []
        paint_eyes = not any(("iris" in n or "pupil" in n) for n in names)
        groups: dict[tuple[Any, ...], list[int]] = {}
        geometry: list[PartGeometry] = []
        for i, (item, name) in enumerate(zip(items, names, strict=True)):
            geometry.append(part_geometry(item, name, face_type, paint_eyes))
            key = (finish_for(name), not item.mesh.is_watertight, bool(geometry[-1].colors[:, 3].min() < 1.0))
            groups.setdefault(key, []).append(i)
        for order, ((finish, double_sided, blend), indices) in enumerate(groups.items()):
            material = self.pyrender.MetallicRoughnessMaterial(
                baseColorFactor=np.ones(4),
                metallicFactor=finish.metallic,
                roughnessFactor=finish.roughness,
                alphaMode="BLEND" if blend else "OPAQUE",
                doubleSided=double_sided,
            )
            batch = RigidBatch(self.pyrender, [geometry[i] for i in indices], material)
            # a fixed draw order (pyrender's is a set's): open overlays (iris and pupil discs lying on the
            # eyeball) before closed parts, so they win depth ties; the same image in every process
            batch.mesh.draw_order = order if double_sided else 100 + order
            self._batch_nodes[id(batch)] = self.scene.add(batch.mesh, pose=np.eye(4))
            self._batches.append((batch, indices))

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
        for batch, _ in self._batches:
            batch.upload()
        for buffers, _ in self._deformable.values():
            buffers.upload()
