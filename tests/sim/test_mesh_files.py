"""User mesh files (sim/heads/meshes.py) are read bounded: a FIFO, a device or a directory is refused before
it is opened, a file over MESH_LIMIT_BYTES before it is read, and so is each file a mesh names beside it;
every format the profiles use still loads from memory exactly as trimesh loads it from its path."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
from PIL import Image
from servoface.calibration import boundedfile
from servoface.sim.errors import HeadMeshError
from servoface.sim.heads import builtin_profile_dir, meshes
from servoface.sim.heads.meshes import load_part_mesh, load_skin_mesh

from tests.fifo import settle

WHERE = "head.toml: skin.mesh"
POSIX = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs need a POSIX system")


def _coloured() -> trimesh.Trimesh:
    sphere: trimesh.Trimesh = trimesh.creation.icosphere(subdivisions=2, radius=40.0)
    rgba = np.random.default_rng(0).integers(0, 256, (len(sphere.vertices), 4), dtype=np.uint8)
    return trimesh.Trimesh(sphere.vertices, sphere.faces, vertex_colors=rgba, process=False)


def _write(kind: str, folder: Path) -> str:
    """A mesh file of ``kind`` in ``folder`` (with the files it names, if any); its name."""
    mesh = _coloured()
    if kind == "stl-ascii":
        (folder / "m.stl").write_text(trimesh.exchange.stl.export_stl_ascii(mesh))
        return "m.stl"
    if kind == "ply-ascii":
        (folder / "m.ply").write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="ascii"))
        return "m.ply"
    if kind == "obj-textured":
        uv = np.random.default_rng(1).random((len(mesh.vertices), 2))
        image = Image.new("RGB", (8, 8), (200, 10, 10))
        mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=image)  # type: ignore[no-untyped-call]
        mesh.export(folder / "m.obj")  # and material.mtl, material_0.png
        assert (folder / "material.mtl").is_file()
        return "m.obj"
    if kind == "gltf":
        files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(mesh))  # type: ignore[no-untyped-call]
        for name, data in files.items():
            (folder / name).write_bytes(data)  # model.gltf and its .bin buffers
        return "model.gltf"
    mesh.export(folder / f"m.{kind}")
    return f"m.{kind}"


@pytest.mark.parametrize("kind", ["stl", "stl-ascii", "obj", "obj-textured", "ply", "ply-ascii", "glb", "gltf", "off"])
def test_every_format_loads_as_trimesh_loads_it_from_its_path(kind: str, tmp_path: Path) -> None:
    name = _write(kind, tmp_path)
    before: Any = trimesh.load(str(tmp_path / name), force="mesh", process=False)  # how it was read until now
    v, f, c = load_skin_mesh(name, tmp_path, WHERE)
    np.testing.assert_array_equal(v, np.asarray(before.vertices, dtype=np.float64))
    np.testing.assert_array_equal(f, np.asarray(before.faces, dtype=np.int64))
    if before.visual.kind == "vertex":
        np.testing.assert_array_equal(c, np.asarray(before.visual.vertex_colors, dtype=np.float64)[:, :4] / 255.0)
    else:
        np.testing.assert_array_equal(c, np.tile([0.86, 0.70, 0.60, 1.0], (len(v), 1)))
    part = load_part_mesh(name, tmp_path, WHERE, scale=25.4)  # a mesh in inches (1 m across: within 10 m)
    np.testing.assert_array_equal(part.vertices, np.asarray(before.vertices) * 25.4)
    np.testing.assert_array_equal(part.faces, before.faces)


@POSIX
def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    fifo = tmp_path / "face.stl"
    os.mkfifo(fifo)
    err = settle(lambda: load_skin_mesh("face.stl", tmp_path, WHERE), fifo)
    assert isinstance(err, HeadMeshError)
    assert str(err) == f"{WHERE}: {fifo}: a pipe (FIFO), not a regular file; expected a mesh file"


def test_a_directory_is_refused(tmp_path: Path) -> None:
    """(A device is refused the same way, by the shared reader: see the symlink test below.)"""
    (tmp_path / "folder.stl").mkdir()
    with pytest.raises(HeadMeshError) as info:
        load_part_mesh("folder.stl", tmp_path, WHERE)
    assert (
        str(info.value) == f"{WHERE}: {tmp_path / 'folder.stl'}: a directory, not a regular file; expected a mesh file"
    )


def test_a_mesh_name_linked_to_a_device_is_refused_as_a_device(tmp_path: Path) -> None:
    """The format is the suffix of the name the profile wrote, not of what a symlink points at: a link
    ``face.stl`` to ``/dev/zero`` is refused as a device by the bounded reader (not as a wrong suffix, and
    never read)."""
    (tmp_path / "face.stl").symlink_to("/dev/zero")
    with pytest.raises(HeadMeshError) as info:
        load_skin_mesh("face.stl", tmp_path, WHERE)
    assert str(info.value) == f"{WHERE}: /dev/zero: a device, not a regular file; expected a mesh file"


def test_a_mesh_name_linked_to_a_file_without_a_suffix_loads(tmp_path: Path) -> None:
    name = _write("stl", tmp_path)
    (tmp_path / name).rename(tmp_path / "blob")
    (tmp_path / "face.stl").symlink_to(tmp_path / "blob")
    mesh = load_part_mesh("face.stl", tmp_path, WHERE)
    assert len(mesh.faces) > 0


def test_a_file_over_the_limit_is_refused_unopened(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    name = _write("stl", tmp_path)
    size = (tmp_path / name).stat().st_size
    monkeypatch.setattr(meshes, "MESH_LIMIT_BYTES", 1024)

    def no_open(*args: object, **kwargs: object) -> int:
        raise AssertionError("a file over the limit was opened")

    monkeypatch.setattr(boundedfile.os, "open", no_open)
    with pytest.raises(HeadMeshError) as info:
        load_skin_mesh(name, tmp_path, WHERE)
    assert str(info.value) == f"{WHERE}: {tmp_path / name}: {size // 1024} KiB; a mesh file is at most 1 KiB"


def test_the_real_limit_reads_as_a_size(tmp_path: Path) -> None:
    with (tmp_path / "huge.obj").open("wb") as fh:  # sparse: 2.1 GiB declared, no blocks written
        fh.truncate(2_254_857_830)
    with pytest.raises(HeadMeshError, match=r"huge\.obj: 2\.1 GiB; a mesh file is at most 256 MiB$"):
        load_skin_mesh("huge.obj", tmp_path, WHERE)


@POSIX
def test_a_fifo_beside_a_mesh_is_refused_too(tmp_path: Path) -> None:
    """A material library is skipped (as trimesh skips a missing one); a glTF buffer fails the mesh."""
    name = _write("obj-textured", tmp_path)
    before: Any = trimesh.load(str(tmp_path / name), force="mesh", process=False)
    (tmp_path / "material.mtl").unlink()
    os.mkfifo(tmp_path / "material.mtl")
    loaded = settle(lambda: load_skin_mesh(name, tmp_path, WHERE), tmp_path / "material.mtl")
    assert isinstance(loaded, tuple), loaded
    np.testing.assert_array_equal(loaded[0], before.vertices)
    np.testing.assert_array_equal(loaded[1], before.faces)

    gltf = tmp_path / "gltf"
    gltf.mkdir()
    name = _write("gltf", gltf)
    buffer = sorted(gltf.glob("*.bin"))[0]
    buffer.unlink()
    os.mkfifo(buffer)
    err = settle(lambda: load_skin_mesh(name, gltf, WHERE), buffer)
    assert isinstance(err, HeadMeshError)
    assert str(err) == (
        f"{WHERE}: could not read mesh {gltf / name}: {buffer}: a pipe (FIFO), not a regular file; "
        "expected a mesh's material, texture or buffer file"
    )


@POSIX
def test_check_refuses_a_profile_naming_a_fifo_mesh(tmp_path: Path) -> None:
    """`servoface check` on a profile whose skin is a FIFO: exit 2 and the message, not a hang or a traceback."""
    folder = tmp_path / "my_head"
    shutil.copytree(builtin_profile_dir("human"), folder)
    profile = folder / "head.toml"
    text = profile.read_text()
    assert 'mesh = "builtin:human_skin"' in text, "test setup: the human profile names its skin"
    profile.write_text(text.replace('mesh = "builtin:human_skin"', 'mesh = "face.stl"'))
    os.mkfifo(folder / "face.stl")
    proc = subprocess.run(
        [sys.executable, "-m", "servoface.controller.cli", "check", str(folder), "--no-report"],
        capture_output=True,
        text=True,
        timeout=120,  # a regression that waits on the FIFO fails here instead of hanging
        env={**os.environ, "PYOPENGL_PLATFORM": "egl"},
    )
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    first = proc.stderr.splitlines()[0]
    assert first == (
        f"servoface check: {profile}: skin.mesh: {folder / 'face.stl'}: a pipe (FIFO), not a regular file; "
        "expected a mesh file"
    ), proc.stderr
