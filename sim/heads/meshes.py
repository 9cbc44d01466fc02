"""Resolve the ``mesh = ...`` keys of a head profile: ``"builtin:<name>"`` or a file (STL/OBJ/GLB/PLY).

User meshes are read with ``trimesh.load(..., force="mesh", process=False)`` (vertices are kept as they
are: merging would close slits such as a mouth) and scaled by the profile's ``scale`` (e.g. 1000 for a
CAD export in metres).

The file is read through :func:`servoface.calibration.boundedfile.read_bounded` and parsed from memory: a
directory, a device or a FIFO is refused before it is opened, a file over ``MESH_LIMIT_BYTES`` (256 MiB,
far beyond any real head part) before a byte is read. The files a mesh names beside it (an OBJ's material
library and textures, a glTF's buffers) are read the same way by a trimesh resolver; a refused material or
texture is skipped as trimesh skips a missing one, a refused glTF buffer fails the mesh.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

import numpy as np
from servoface.calibration.boundedfile import MESH_LIMIT_BYTES, read_bounded
from servoface.sim.errors import HeadMeshError
from servoface.sim.heads import builtin
from servoface.sim.heads.mesh_tools import F64, I64
from servoface.sim.heads.sizes import COORD_LIMIT_MM

BUILTIN_PREFIX = "builtin:"
MESH_SUFFIXES = (".stl", ".obj", ".glb", ".gltf", ".ply", ".off")


def _read_file(spec: str, folder: Path, where: str) -> Any:
    import trimesh

    named = folder / spec  # its suffix as written says the format (a symlink may point at any name)
    path = named.resolve()
    if named.suffix.lower() not in MESH_SUFFIXES:
        raise HeadMeshError(
            f"{where}: expected a mesh file ending in {list(MESH_SUFFIXES)} or builtin:<name>, got {spec!r}"
        )
    try:
        data = _read_bounded(path, f"{where}: ", "a mesh file")
    except (FileNotFoundError, NotADirectoryError) as err:
        raise HeadMeshError(f"{where}: expected an existing mesh file, {path} not found") from err
    except OSError as err:
        raise HeadMeshError(f"{where}: could not read mesh {path}: {err}") from err
    try:
        suffix = named.suffix.lower().removeprefix(".")
        mesh = trimesh.load(io.BytesIO(data), file_type=suffix, resolver=_assets(path), force="mesh", process=False)
    except Exception as err:  # trimesh raises many kinds; report them all the same way
        raise HeadMeshError(f"{where}: could not read mesh {path}: {err}") from err
    v = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64)
    f = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64)
    if len(v) < 3 or len(f) < 1 or f.ndim != 2 or f.shape[1] != 3:
        raise HeadMeshError(f"{where}: expected a triangle mesh, {path} has {len(v)} vertices / {len(f)} faces")
    if not np.all(np.isfinite(v)):
        raise HeadMeshError(f"{where}: mesh {path} has non-finite vertex coordinates")
    return mesh


def _read_bounded(path: Path, prefix: str, what: str) -> bytes:
    """The bytes of ``path``; HeadMeshError ``"{prefix}{path}: {reason}"`` if it is not a regular file or is
    over ``MESH_LIMIT_BYTES``."""
    return read_bounded(
        path, lambda reason: HeadMeshError(f"{prefix}{path}: {reason}"), what=what, limit_bytes=MESH_LIMIT_BYTES
    )


def _assets(path: Path) -> Any:
    """A trimesh resolver for the files the mesh at ``path`` names beside it, read bounded (see above); as
    trimesh's own it looks a name up as written, without a leading slash, then by its last part, and never
    outside the mesh's folder."""
    from trimesh.resolvers import FilePathResolver

    class BoundedAssets(FilePathResolver):
        def get(self, name: str) -> bytes:
            root = Path(self.parent).resolve()
            for candidate in (name.strip(), name.strip().lstrip("/"), os.path.basename(name)):
                asset = (root / candidate).resolve()
                if asset.is_relative_to(root) and asset.exists():
                    return _read_bounded(asset, "", "a mesh's material, texture or buffer file")
            raise FileNotFoundError(f"{name!r}: no such file in {root}")

    return BoundedAssets(str(path))


def load_part_mesh(spec: str, folder: Path, where: str, scale: float = 1.0) -> Any:
    """A trimesh.Trimesh for a rigid part, in the head frame (mm)."""
    import trimesh

    if spec.startswith(BUILTIN_PREFIX):
        name = spec[len(BUILTIN_PREFIX) :]
        if name not in builtin.PART_MESHES:
            raise HeadMeshError(f"{where}: expected a built-in part mesh {sorted(builtin.PART_MESHES)}, got {name!r}")
        mesh = builtin.part_mesh(name)
    else:
        src = _read_file(spec, folder, where)
        mesh = trimesh.Trimesh(np.asarray(src.vertices, dtype=np.float64), np.asarray(src.faces), process=False)
    if scale != 1.0:
        with np.errstate(over="ignore"):  # a scale that overflows is refused just below, by name
            mesh.vertices = np.asarray(mesh.vertices) * scale
    _check_extent(np.asarray(mesh.vertices), spec, where, scale)
    return mesh


def load_skin_mesh(spec: str, folder: Path, where: str, scale: float = 1.0) -> tuple[F64, I64, F64]:
    """(vertices (n, 3) mm, faces (m, 3), vertex colours (n, 4) in 0..1) of a skin."""
    if spec.startswith(BUILTIN_PREFIX):
        name = spec[len(BUILTIN_PREFIX) :]
        if name not in builtin.SKIN_MESHES:
            raise HeadMeshError(f"{where}: expected a built-in skin mesh {sorted(builtin.SKIN_MESHES)}, got {name!r}")
        v, f, c = builtin.skin_mesh(name)
    else:
        src = _read_file(spec, folder, where)
        v = np.asarray(src.vertices, dtype=np.float64).copy()
        f = np.asarray(src.faces, dtype=np.int64).copy()
        c = np.tile([0.86, 0.70, 0.60, 1.0], (len(v), 1))
        vis = getattr(src, "visual", None)
        if vis is not None and getattr(vis, "kind", None) == "vertex":
            c = np.asarray(vis.vertex_colors, dtype=np.float64)[:, :4] / 255.0
    with np.errstate(over="ignore"):  # a scale that overflows is refused just below, by name
        v = v * scale
    _check_extent(v, spec, where, scale)
    return v, f, c


def _check_extent(vertices: F64, spec: str, where: str, scale: float) -> None:
    """HeadMeshError for a mesh with a vertex beyond ``COORD_LIMIT_MM`` of the head's origin once scaled:
    a wrong ``scale`` or unit (a head is well under 1.5 m), and numbers whose squares would overflow."""
    far = float(np.max(np.abs(vertices))) if len(vertices) else 0.0
    if not far <= COORD_LIMIT_MM:
        raise HeadMeshError(
            f"{where}: expected vertices within +-{COORD_LIMIT_MM:g} mm of the head's origin, mesh {spec} "
            f"reaches {far:.6g} mm at scale {scale:g} (a mesh in another unit? set scale to convert it to mm)"
        )
