"""`cover_spheres` with one int64 key per voxel gives exactly the spheres (same order, same bits) of the
straightforward row sort (`np.unique(..., axis=0)`) on every part of both built-in heads; `patch_labels`
equals the row sort on random keys, negatives and the wide-range fallback included."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from servoface.sim.gate.spheres import SphereSet, cover_spheres, patch_labels
from servoface.sim.gate.tss_build import TssParams


def _row_sort_cover(
    mesh: Any, target_count: int = 160, min_cell_mm: float = 1.0, max_cell_mm: float | None = None
) -> SphereSet:
    """The cover as it was built before the 1-D key (labels from `np.unique(keys, axis=0)`)."""
    import trimesh

    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    area = float(mesh.area)
    cell = max(min_cell_mm, float(np.sqrt(max(area, 1e-9) / max(target_count, 1))))
    if max_cell_mm is not None:
        cell = min(cell, max_cell_mm)
    vertices, faces = trimesh.remesh.subdivide_to_size(vertices, faces, max_edge=cell / 2.0, max_iter=12)
    tri = vertices[faces]
    keys = np.floor(tri.mean(axis=1) / cell).astype(np.int64)
    _, label = np.unique(keys, axis=0, return_inverse=True)
    label = label.reshape(-1)
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


@pytest.mark.parametrize("head_name", ["human", "dog"])
def test_cover_equals_the_row_sort_cover_on_builtin_heads(head_name: str) -> None:
    from servoface.sim.heads import load_head

    params = TssParams()
    head = load_head(head_name)
    for part in head.parts:
        for count, max_cell in ((params.spheres_per_part, params.max_cell_mm), (40, None)):
            got = cover_spheres(part.mesh, count, max_cell_mm=max_cell)
            want = _row_sort_cover(part.mesh, count, max_cell_mm=max_cell)
            assert got.centres_mm.tobytes() == want.centres_mm.tobytes(), part.name
            assert got.radii_mm.tobytes() == want.radii_mm.tobytes(), part.name


def test_patch_labels_equal_the_row_sort() -> None:
    rng = np.random.default_rng(17)
    cases = [rng.integers(-50, 50, size=(n, 3)) for n in (1, 2, 7, 500, 20000)]
    cases.append(rng.integers(-3, 3, size=(1000, 3)) * np.array([1, 10**7, 1]))  # one wide column
    cases.append(rng.integers(-(2**40), 2**40, size=(300, 3)))  # radix product beyond int64: fallback
    cases.append(np.zeros((5, 3), dtype=np.int64))
    for keys in cases:
        keys = keys.astype(np.int64)
        _, want = np.unique(keys, axis=0, return_inverse=True)
        assert np.array_equal(patch_labels(keys), want.reshape(-1))
