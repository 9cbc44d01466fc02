"""Smooth (area-weighted) vertex normals, vectorised for a mesh whose vertices move every frame."""

from __future__ import annotations

import numpy as np
import scipy.sparse
from numpy.typing import NDArray


class VertexNormals:
    """Vertex normals of a fixed triangle topology: build once per face array, call once per frame.

    faces: (m, 3) int. Calling with vertices (n, 3) float returns unit normals (n, 3) float32; a vertex
    used by no face (or only by degenerate faces) gets +z.
    """

    def __init__(self, faces: NDArray[np.integer], n_vertices: int) -> None:
        faces = np.asarray(faces, dtype=np.int64)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must be (m, 3) int, got shape {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= n_vertices):
            raise ValueError(f"faces index vertices outside 0..{n_vertices - 1}")
        m = len(faces)
        self.faces = faces
        self.n_vertices = n_vertices
        # (n, m) incidence: sums the (area-weighted) normals of the faces around each vertex
        self._incidence = scipy.sparse.csr_matrix(
            (np.ones(3 * m, dtype=np.float64), (faces.ravel(), np.repeat(np.arange(m), 3))),
            shape=(n_vertices, m),
        )

    def __call__(self, vertices: NDArray[np.floating]) -> NDArray[np.float32]:
        v = np.asarray(vertices, dtype=np.float64)
        if v.shape != (self.n_vertices, 3):
            raise ValueError(f"vertices must be ({self.n_vertices}, 3), got {v.shape}")
        a, b, c = v[self.faces[:, 0]], v[self.faces[:, 1]], v[self.faces[:, 2]]
        face_n = np.cross(b - a, c - a)  # length = 2 * area: area weighting for free
        n = self._incidence @ face_n
        length = np.linalg.norm(n, axis=1)
        bad = length < 1e-12
        n[bad] = (0.0, 0.0, 1.0)
        length[bad] = 1.0
        out: NDArray[np.float32] = (n / length[:, None]).astype(np.float32)
        return out
