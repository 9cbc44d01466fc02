"""Covering spheres for a part's surface (TSS step 1, conservative variant).

Londra grows *inscribed* spheres from triangle midpoints; inscribed spheres can miss a shallow contact
between them. The gate needs "no collision the exact test finds is missed", and the exact test (fcl on
triangle BVHs) fires when surfaces intersect, so here every triangle is covered: the surface is cut into
small patches (triangle centroids binned on a voxel grid after subdividing long edges) and each patch
gets its bounding sphere (centre = middle of the patch's vertex box, radius = farthest vertex). A ball is
convex, so it holds the patch's triangles; any two intersecting triangles lie in two overlapping spheres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SphereSet:
    """Spheres of one part in its rest pose (head frame): centres (n, 3) mm, radii (n,) mm."""

    centres_mm: FloatArray
    radii_mm: FloatArray

    @property
    def n(self) -> int:
        return int(self.radii_mm.shape[0])


def cover_spheres(
    mesh: Any, target_count: int = 160, min_cell_mm: float = 1.0, max_cell_mm: float | None = None
) -> SphereSet:
    """Bounding spheres of about ``target_count`` surface patches of ``mesh`` (a trimesh.Trimesh); with
    ``max_cell_mm`` a large part gets more spheres so none is coarser than that."""
    import trimesh  # heavy import at use

    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0:
        raise GateConfigError("cannot cover an empty mesh with spheres")
    area = float(mesh.area)
    cell = max(min_cell_mm, float(np.sqrt(max(area, 1e-9) / max(target_count, 1))))
    if max_cell_mm is not None:
        cell = min(cell, max_cell_mm)
    subdivide = trimesh.remesh.subdivide_to_size
    vertices, faces = subdivide(vertices, faces, max_edge=cell / 2.0, max_iter=12)  # type: ignore[no-untyped-call]
    tri = vertices[faces]  # (m, 3, 3)
    keys = np.floor(tri.mean(axis=1) / cell).astype(np.int64)
    label = patch_labels(keys)
    n = int(label.max()) + 1
    pts = tri.reshape(-1, 3)
    plabel = np.repeat(label, 3)
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, plabel, pts)
    np.maximum.at(hi, plabel, pts)
    centres = (lo + hi) / 2.0
    radii = np.zeros(n)
    np.maximum.at(radii, plabel, np.linalg.norm(pts - centres[plabel], axis=1))
    return SphereSet(centres, radii * (1.0 + 1e-9) + 1e-9)


def patch_labels(keys: NDArray[np.int64]) -> NDArray[np.int64]:
    """Label of each row of ``keys`` (m, 3) voxel integers: the rank of its row among the distinct rows in
    lexicographic order, as ``np.unique(keys, axis=0, return_inverse=True)`` gives, but sorting one int64
    per row (each column shifted to start at 0, mixed radix) instead of rows; falls back to the row sort
    when the radix product would not fit in an int64."""
    if keys.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    lo = keys.min(axis=0)
    span = keys.max(axis=0) - lo + 1
    if float(span[0]) * float(span[1]) * float(span[2]) >= 2.0**62:
        _, label = np.unique(keys, axis=0, return_inverse=True)
        return np.asarray(label, dtype=np.int64).reshape(-1)
    shifted = keys - lo
    code = (shifted[:, 0] * span[1] + shifted[:, 1]) * span[2] + shifted[:, 2]
    _, label = np.unique(code, return_inverse=True)
    return np.asarray(label, dtype=np.int64).reshape(-1)
