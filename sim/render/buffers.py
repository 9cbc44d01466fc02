"""GPU vertex buffers that are rewritten in place every frame, and rigid parts batched into them.

pyrender uploads a primitive's vertices once (``GL_STATIC_DRAW``) and offers no update; rebuilding a
pyrender mesh per frame re-creates every GL object. Here each primitive keeps its interleaved vertex data
host-side (position, normal[, colour], the layout pyrender itself uses) and a frame writes it into the
existing GL buffer with one ``glBufferSubData``.

Rigid parts are batched: all parts with the same surface finish become ONE primitive whose vertices are
moved on the CPU (a 3x4 transform per part, numpy). Drawing 3-4 primitives instead of ~20 removes most
of pyrender's per-primitive Python overhead (uniforms and lights are set per primitive).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

F32 = NDArray[np.float32]


class DynamicPrimitive:
    """A pyrender Primitive whose positions and normals are replaced every frame.

    faces: (m, 3) uint32; colors: optional (n, 4) linear RGBA per vertex (constant).
    """

    def __init__(
        self,
        pyrender: Any,
        faces: NDArray[np.integer],
        n_vertices: int,
        material: Any,
        colors: F32 | None = None,
    ) -> None:
        self.n_vertices = n_vertices
        self.faces = np.ascontiguousarray(faces, dtype=np.uint32)
        up = np.tile(np.array([0.0, 0.0, 1.0], dtype=np.float32), (n_vertices, 1))
        self.prim = pyrender.Primitive(
            positions=np.zeros((n_vertices, 3), np.float32),
            normals=up,
            color_0=None if colors is None else np.ascontiguousarray(colors, dtype=np.float32),
            indices=self.faces,
            material=material,
        )
        self.buf = np.zeros((n_vertices, 6 if colors is None else 10), dtype=np.float32)
        if colors is not None:
            self.buf[:, 6:] = colors
        self._pending = False

    def set(self, positions: NDArray[np.floating], normals: NDArray[np.floating]) -> None:
        self.buf[:, :3] = positions
        self.buf[:, 3:6] = normals
        if not self.prim._in_context():  # first draw: pyrender builds the buffer from these
            self.prim.positions = self.buf[:, :3].copy()
            self.prim.normals = self.buf[:, 3:6].copy()
        self._pending = True

    def upload(self) -> None:
        """Write the frame's vertices into the GL buffer (GL context current)."""
        if not self._pending or not self.prim._in_context():
            return
        from OpenGL import GL

        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.prim._buffers[0])
        GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, self.buf.nbytes, self.buf)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        self._pending = False


@dataclass(frozen=True)
class PartGeometry:
    """A rigid part ready to draw: rest positions/normals (n, 3), faces (m, 3), linear colours (n, 4)."""

    name: str
    positions: NDArray[np.float64]
    normals: NDArray[np.float64]
    faces: NDArray[np.int64]
    colors: F32


class RigidBatch:
    """Several rigid parts drawn as one primitive; each frame moves each part by its own 4x4 transform."""

    def __init__(self, pyrender: Any, parts: Sequence[PartGeometry], material: Any) -> None:
        sizes = [len(p.positions) for p in parts]
        starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        self.names = [p.name for p in parts]
        self.slices = [slice(int(a), int(b)) for a, b in zip(starts[:-1], starts[1:], strict=True)]
        self.rest_pos = np.concatenate([p.positions for p in parts]).astype(np.float64)
        self.rest_nrm = np.concatenate([p.normals for p in parts]).astype(np.float64)
        faces = np.concatenate([p.faces + s for p, s in zip(parts, starts[:-1], strict=True)])
        colors = np.concatenate([p.colors for p in parts]).astype(np.float32)
        self.dyn = DynamicPrimitive(pyrender, faces, len(self.rest_pos), material, colors)
        self.mesh = pyrender.Mesh([self.dyn.prim])
        self._pos = self.rest_pos.astype(np.float32)
        self._nrm = self.rest_nrm.astype(np.float32)
        self._last: list[NDArray[np.float64] | None] = [None] * len(parts)

    def set_transforms(self, transforms: Sequence[NDArray[np.float64]]) -> None:
        """One (4, 4) transform per part, in the order the parts were given."""
        changed = False
        for i, (sl, tf) in enumerate(zip(self.slices, transforms, strict=True)):
            last = self._last[i]
            if last is not None and np.array_equal(last, tf):
                continue
            rot = tf[:3, :3]
            self._pos[sl] = self.rest_pos[sl] @ rot.T + tf[:3, 3]
            self._nrm[sl] = self.rest_nrm[sl] @ rot.T
            self._last[i] = np.array(tf, dtype=np.float64)
            changed = True
        if changed:
            self.dyn.set(self._pos, self._nrm)

    def upload(self) -> None:
        self.dyn.upload()
