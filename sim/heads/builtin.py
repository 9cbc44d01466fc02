"""Built-in procedural meshes, named in head profiles as ``mesh = "builtin:<name>"``.

Each generator is deterministic (same bytes on every call and machine) and cached per process.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np
from servoface.sim.heads import dog_gen, human_gen
from servoface.sim.heads.mesh_tools import F64, I64

MeshFn = Callable[[], tuple[F64, I64]]


def _sided(fn: Callable[[float], tuple[F64, I64]], side: float) -> MeshFn:
    return lambda: fn(side)


def _lid(fn: Callable[[float, bool], tuple[F64, I64]], side: float, upper: bool) -> MeshFn:
    return lambda: fn(side, upper)


def _crease(fn: Callable[[float, bool, bool], tuple[F64, I64]], side: float) -> MeshFn:
    return lambda: fn(side, True, True)


def _human() -> dict[str, MeshFn]:
    h = human_gen
    out: dict[str, MeshFn] = {
        "human_skull": h.skull,
        "human_jaw": h.jaw,
        "human_teeth_upper": h.teeth_upper,
        "human_mouth_cavity": h.mouth_cavity,
        "human_neck": h.neck,
    }
    for tag, side in (("l", 1.0), ("r", -1.0)):
        out[f"human_eyeball_{tag}"] = _sided(h.eyeball, side)
        out[f"human_iris_{tag}"] = _sided(h.iris, side)
        out[f"human_pupil_{tag}"] = _sided(h.pupil, side)
        out[f"human_eye_socket_{tag}"] = _sided(h.eye_socket, side)
        out[f"human_ear_{tag}"] = _sided(h.ear, side)
        out[f"human_upper_lid_{tag}"] = _lid(h.eyelid, side, True)
        out[f"human_lower_lid_{tag}"] = _lid(h.eyelid, side, False)
        out[f"human_upper_lash_{tag}"] = _lid(h.lid_line, side, True)
        out[f"human_lower_lash_{tag}"] = _lid(h.lid_line, side, False)
        out[f"human_lid_crease_{tag}"] = _crease(h.lid_line, side)
    return out


def _dog() -> dict[str, MeshFn]:
    d = dog_gen
    out: dict[str, MeshFn] = {
        "dog_skull": d.skull,
        "dog_jaw": d.jaw,
        "dog_teeth_upper": d.teeth_upper,
        "dog_mouth_cavity": d.mouth_cavity,
        "dog_neck": d.neck,
        "dog_neck_collar": d.neck_collar,
        "dog_nose": d.nose,
        "dog_tongue_root": d.tongue_root,
        "dog_tongue_tip": d.tongue_tip,
    }
    for tag, side in (("l", 1.0), ("r", -1.0)):
        out[f"dog_eyeball_{tag}"] = _sided(d.eyeball, side)
        out[f"dog_iris_{tag}"] = _sided(d.iris, side)
        out[f"dog_pupil_{tag}"] = _sided(d.pupil, side)
        out[f"dog_eye_socket_{tag}"] = _sided(d.eye_socket, side)
        out[f"dog_ear_{tag}"] = _sided(d.ear, side)
        out[f"dog_upper_lid_{tag}"] = _lid(d.eyelid, side, True)
    return out


PART_MESHES: dict[str, MeshFn] = {**_human(), **_dog()}
SKIN_MESHES: dict[str, Callable[[], tuple[F64, I64, F64]]] = {
    "human_skin": human_gen.skin,
    "dog_skin": dog_gen.skin,
}


def names() -> list[str]:
    return sorted([*PART_MESHES, *SKIN_MESHES])


@lru_cache(maxsize=128)
def _part(name: str) -> tuple[bytes, bytes, tuple[int, ...], tuple[int, ...]]:
    v, f = PART_MESHES[name]()
    v = np.ascontiguousarray(v, dtype=np.float64)
    f = np.ascontiguousarray(f, dtype=np.int64)
    return v.tobytes(), f.tobytes(), v.shape, f.shape


def part_mesh(name: str) -> Any:
    """A fresh trimesh.Trimesh for a built-in part mesh (KeyError if unknown)."""
    import trimesh

    vb, fb, vs, fs = _part(name)
    v = np.frombuffer(vb, dtype=np.float64).reshape(vs).copy()
    f = np.frombuffer(fb, dtype=np.int64).reshape(fs).copy()
    return trimesh.Trimesh(vertices=v, faces=f, process=False)


def skin_mesh(name: str) -> tuple[F64, I64, F64]:
    """(vertices (n, 3), faces (m, 3), vertex colours (n, 4)) of a built-in skin."""
    return SKIN_MESHES[name]()
