"""Exact collision test between posed part meshes: python-fcl on the triangle BVHs trimesh builds.

Only the pairs the TSS broad phase flags come here. python-fcl is imported at use, with an install hint.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError

FloatArray = NDArray[np.float64]


def _fcl() -> Any:
    try:
        import fcl
    except ImportError as err:
        raise GateConfigError("the twin gate's exact collision test needs python-fcl: pip install python-fcl") from err
    return fcl


def eroded(mesh: Any, tolerance_mm: float) -> Any:
    """``mesh`` with every vertex moved inwards by ``tolerance_mm / 2`` along its normal, so two parts
    whose eroded copies intersect penetrate by about more than ``tolerance_mm``. Identity for 0."""
    if tolerance_mm <= 0.0:
        return mesh
    import trimesh

    v = np.asarray(mesh.vertices) - np.asarray(mesh.vertex_normals) * (tolerance_mm / 2.0)
    return trimesh.Trimesh(v, np.asarray(mesh.faces), process=False)


class ExactCollider:
    """fcl collision objects for named meshes (rest pose, head frame), tested pairwise under transforms."""

    def __init__(self, meshes: Mapping[str, Any]) -> None:
        fcl = _fcl()
        from trimesh.collision import mesh_to_BVH

        self._fcl = fcl
        bvh = {name: mesh_to_BVH(mesh) for name, mesh in meshes.items()}  # type: ignore[no-untyped-call]
        self._objects = {name: fcl.CollisionObject(model, fcl.Transform()) for name, model in bvh.items()}
        self._request = fcl.CollisionRequest()

    def _place(self, name: str, transform: FloatArray) -> Any:
        obj = self._objects[name]
        obj.setTransform(self._fcl.Transform(np.asarray(transform[:3, :3]), np.asarray(transform[:3, 3])))
        return obj

    def collide(self, a: str, b: str, transform_a: FloatArray, transform_b: FloatArray) -> bool:
        """True when the meshes of ``a`` and ``b`` intersect under the given (4, 4) transforms."""
        oa = self._place(a, transform_a)
        ob = self._place(b, transform_b)
        result = self._fcl.CollisionResult()
        return bool(self._fcl.collide(oa, ob, self._request, result) > 0)

    def distance(self, a: str, b: str, transform_a: FloatArray, transform_b: FloatArray) -> float:
        """fcl's exact distance (mm) between the meshes of ``a`` and ``b`` under the given transforms
        (0 or less when they intersect)."""
        oa = self._place(a, transform_a)
        ob = self._place(b, transform_b)
        return float(self._fcl.distance(oa, ob, self._fcl.DistanceRequest(), self._fcl.DistanceResult()))

    def colliding(
        self, pairs: Sequence[tuple[str, str]], transforms: Mapping[str, FloatArray]
    ) -> list[tuple[str, str]]:
        """The pairs (of those given) that intersect."""
        return [(a, b) for a, b in pairs if self.collide(a, b, transforms[a], transforms[b])]
