"""Forward kinematics of a head: joint tree -> 4x4 transforms, posed rigid parts, skinned skin.

Every joint is a revolute joint whose ``pivot_mm`` and ``axis`` are given in the head frame with all
joints at 0 deg, so a joint's world transform is ``W_parent @ T(p) R(axis, angle) T(-p)``. Angles past a
joint's limits are clamped to the limit (the rig has hard stops, like the robot).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.errors import PoseError
from servoface.sim.head import Head
from servoface.sim.rig import HeadPose, JointActuator

Transform = NDArray[np.float64]  # (4, 4) float


@dataclass(frozen=True)
class PosedPart:
    """A rigid part placed for a pose: ``mesh`` is already in the head frame; ``transform`` (4, 4) maps
    the rest mesh to it."""

    name: str
    mesh: Any  # trimesh.Trimesh
    color_rgba: tuple[float, float, float, float]
    transform: Transform
    collides: bool = True


@dataclass(frozen=True)
class _Tables:
    names: tuple[str, ...]
    parent: tuple[int, ...]  # -1 = head base
    pivot: NDArray[np.float64]  # (J, 3)
    axis: NDArray[np.float64]  # (J, 3) unit
    lower: NDArray[np.float64]  # (J,)
    upper: NDArray[np.float64]
    neutral: NDArray[np.float64]
    index: dict[str, int]


_TABLES: dict[int, tuple[Head, _Tables]] = {}


def _tables(head: Head) -> _Tables:
    hit = _TABLES.get(id(head))
    if hit is not None and hit[0] is head:
        return hit[1]
    index = {j.name: i for i, j in enumerate(head.joints)}
    t = _Tables(
        names=tuple(index),
        parent=tuple(-1 if j.parent is None else index[j.parent] for j in head.joints),
        pivot=np.array([j.pivot_mm for j in head.joints], dtype=np.float64).reshape(-1, 3),
        axis=np.array([_unit(j.axis) for j in head.joints], dtype=np.float64).reshape(-1, 3),
        lower=np.array([j.lower_deg for j in head.joints], dtype=np.float64),
        upper=np.array([j.upper_deg for j in head.joints], dtype=np.float64),
        neutral=np.array([j.neutral_deg for j in head.joints], dtype=np.float64),
        index=index,
    )
    if len(_TABLES) > 64:
        _TABLES.clear()
    _TABLES[id(head)] = (head, t)
    return t


def _unit(v: tuple[float, float, float]) -> tuple[float, float, float]:
    n = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
    return (v[0] / n, v[1] / n, v[2] / n)


def rotation_about_axis(axis: NDArray[np.float64], angle_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rodrigues, vectorised: axis (J, 3) unit, angle (J,) rad -> (J, 3, 3) rotation matrices."""
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    C = 1.0 - c
    r = np.empty((axis.shape[0], 3, 3))
    r[:, 0, 0] = c + x * x * C
    r[:, 0, 1] = x * y * C - z * s
    r[:, 0, 2] = x * z * C + y * s
    r[:, 1, 0] = y * x * C + z * s
    r[:, 1, 1] = c + y * y * C
    r[:, 1, 2] = y * z * C - x * s
    r[:, 2, 0] = z * x * C - y * s
    r[:, 2, 1] = z * y * C + x * s
    r[:, 2, 2] = c + z * z * C
    return r


def joint_angles(head: Head, joint_deg: Mapping[str, float] | None) -> NDArray[np.float64]:
    """(J,) float: the angle of every joint in ``head.joints`` order, missing -> neutral, clamped to limits.

    Raises PoseError for an unknown joint name or a non-finite angle.
    """
    t = _tables(head)
    q = t.neutral.copy()
    if joint_deg:
        for name, value in joint_deg.items():
            i = t.index.get(name)
            if i is None:
                raise PoseError(f"head {head.name!r} has no joint {name!r}; joints: {list(t.names)}")
            v = float(value)
            if not math.isfinite(v):
                raise PoseError(f"joint {name!r}: angle must be finite, got {value!r}")
            q[i] = v
    return np.clip(q, t.lower, t.upper)


def clamp_to_limits(head: Head, joint_deg: Mapping[str, float]) -> dict[str, float]:
    """The same joints, each clamped to its limits."""
    q = joint_angles(head, joint_deg)
    idx = _tables(head).index
    return {name: float(q[idx[name]]) for name in joint_deg}


def transforms_array(head: Head, joint_deg: Mapping[str, float] | None) -> NDArray[np.float64]:
    """(J, 4, 4) float: world transform of every joint, in ``head.joints`` order."""
    t = _tables(head)
    q = np.radians(joint_angles(head, joint_deg))
    rot = rotation_about_axis(t.axis, q)
    # local = T(p) R T(-p): translation p - R p
    trans = t.pivot - np.einsum("jab,jb->ja", rot, t.pivot)
    local = np.zeros((len(q), 4, 4))
    local[:, :3, :3] = rot
    local[:, :3, 3] = trans
    local[:, 3, 3] = 1.0
    world = np.empty_like(local)
    for i, p in enumerate(t.parent):
        world[i] = local[i] if p < 0 else world[p] @ local[i]
    return world


def joint_transforms(head: Head, joint_deg: Mapping[str, float] | None) -> dict[str, Transform]:
    """joint name -> (4, 4) world transform (head frame) for the given angles (deg; missing = neutral)."""
    world = transforms_array(head, joint_deg)
    return {name: world[i] for i, name in enumerate(_tables(head).names)}


def neutral_pose(head: Head) -> HeadPose:
    """Every joint at its neutral angle, skin at rest, every actuator at its neutral target."""
    targets: dict[str, float] = {}
    for a in head.actuators:
        targets[a.role] = a.neutral_deg if isinstance(a, JointActuator) else a.neutral_mm
    return HeadPose(
        joint_deg=dict(head.neutral_joint_deg),
        skin_offset_mm=np.zeros_like(head.skin.vertices_mm),
        actuator_targets=targets,
    )


@lru_cache(maxsize=32)
def _skin_columns(head_id: int, joint_names: tuple[str, ...], all_names: tuple[str, ...]) -> tuple[int, ...]:
    idx = {n: i for i, n in enumerate(all_names)}
    return tuple(idx[n] for n in joint_names)


def skin_transforms(head: Head, world: NDArray[np.float64]) -> NDArray[np.float64]:
    """(K + 1, 4, 4): identity (head base) then the world transform of each of ``head.skin.joint_names``."""
    cols = _skin_columns(id(head), head.skin.joint_names, _tables(head).names)
    out = np.empty((len(cols) + 1, 4, 4))
    out[0] = np.eye(4)
    if cols:
        out[1:] = world[list(cols)]
    return out


def linear_blend(
    vertices_mm: NDArray[np.float64], weights: NDArray[np.float64], transforms: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Linear-blend skinning: vertices (n, 3), weights (n, K), transforms (K, 4, 4) -> (n, 3)."""
    blended = weights @ transforms[:, :3, :].reshape(len(transforms), 12)  # (n, 12)
    m = blended.reshape(-1, 3, 4)
    out: NDArray[np.float64] = np.einsum("nab,nb->na", m[:, :, :3], vertices_mm) + m[:, :, 3]
    return out


def _check_offsets(head: Head, offsets: NDArray[np.float64]) -> NDArray[np.float64]:
    arr = np.asarray(offsets, dtype=np.float64)
    if arr.shape != head.skin.vertices_mm.shape:
        raise PoseError(
            f"skin_offset_mm must have shape {head.skin.vertices_mm.shape} for head {head.name!r}, got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise PoseError("skin_offset_mm must be finite")
    return arr


def posed_skin_vertices(head: Head, pose: HeadPose) -> NDArray[np.float64]:
    """(n, 3) float: skin vertices: rest + ``pose.skin_offset_mm``, then linear-blend skinning."""
    offsets = _check_offsets(head, pose.skin_offset_mm)
    world = transforms_array(head, pose.joint_deg)
    return linear_blend(head.skin.vertices_mm + offsets, head.skin.weights, skin_transforms(head, world))


def part_transforms(head: Head, joint_deg: Mapping[str, float] | None) -> dict[str, Transform]:
    """part name -> (4, 4) transform of its rest mesh for the given angles."""
    world = transforms_array(head, joint_deg)
    idx = _tables(head).index
    eye = np.eye(4)
    return {p.name: (eye if p.joint is None else world[idx[p.joint]]) for p in head.parts}


def posed_parts(head: Head, pose: HeadPose) -> list[PosedPart]:
    """Every rigid part, its mesh moved into place for ``pose`` (new trimesh objects; rest untouched)."""
    import trimesh

    tfs = part_transforms(head, pose.joint_deg)
    out: list[PosedPart] = []
    for part in head.parts:
        tf = tfs[part.name]
        verts = np.asarray(part.mesh.vertices) @ tf[:3, :3].T + tf[:3, 3]
        mesh: Any = trimesh.Trimesh(vertices=verts, faces=np.asarray(part.mesh.faces), process=False)
        visual: Any = getattr(part.mesh, "visual", None)
        if visual is not None and visual.kind == "vertex":
            mesh.visual.vertex_colors = np.asarray(visual.vertex_colors)
        out.append(PosedPart(part.name, mesh, part.color_rgba, tf, part.collides))
    return out
