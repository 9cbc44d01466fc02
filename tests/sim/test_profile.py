"""Head profiles: a copied user profile with its own meshes loads; every bad profile names file and key."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh
from servoface.sim.errors import HeadMeshError, HeadProfileError
from servoface.sim.heads import builtin_profile_dir, load_head
from servoface.sim.profile import load_profile


def _copy(tmp_path: Path, name: str = "human") -> Path:
    dst = tmp_path / f"my_{name}"
    shutil.copytree(builtin_profile_dir(name), dst)
    return dst


def _edit(folder: Path, old: str, new: str, count: int = 1) -> None:
    f = folder / "head.toml"
    text = f.read_text()
    assert text.count(old) >= 1, f"test setup: {old!r} not in head.toml"
    f.write_text(text.replace(old, new, count))


def test_copied_builtin_folder_loads_with_user_meshes(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    (folder / "meshes").mkdir()
    # a user jaw as STL in metres, and a user skin as OBJ
    jaw = load_head("human").part("jaw").mesh.copy()
    jaw.apply_scale(0.001)
    jaw.export(folder / "meshes" / "jaw.stl")
    skin = load_head("human").skin
    trimesh.Trimesh(np.asarray(skin.vertices_mm), np.asarray(skin.faces), process=False).export(
        folder / "meshes" / "face.obj"
    )
    _edit(folder, 'mesh = "builtin:human_jaw"', 'mesh = "meshes/jaw.stl"\nscale = 1000.0')
    _edit(folder, 'mesh = "builtin:human_skin"', 'mesh = "meshes/face.obj"')
    _edit(folder, 'name = "human"', 'name = "my_head"')
    head = load_head(folder)
    assert head.name == "my_head" and head.profile_dir == folder
    assert head.calibration_path == folder / "calibration.json"
    np.testing.assert_allclose(head.part("jaw").mesh.bounds, load_head("human").part("jaw").mesh.bounds, atol=1e-3)
    assert len(head.skin.vertices_mm) == len(skin.vertices_mm)
    assert len(head.actuators) == 30


def test_user_glb_part_mesh_loads(tmp_path: Path) -> None:
    folder = _copy(tmp_path, "dog")
    ear = load_head("dog").part("ear_l").mesh.copy()
    ear.export(folder / "ear_l.glb")
    _edit(folder, 'mesh = "builtin:dog_ear_l"', 'mesh = "ear_l.glb"')
    head = load_head(folder)
    np.testing.assert_allclose(head.part("ear_l").mesh.bounds, ear.bounds, atol=1e-4)


def test_load_head_by_file_path_and_unknown_names(tmp_path: Path) -> None:
    folder = _copy(tmp_path, "dog")
    assert load_head(folder / "head.toml").name == "dog"
    with pytest.raises(HeadProfileError, match="built-in head name"):
        load_head("cat")


BAD_CASES = [
    # (old text, new text, expected fragment of the error message)
    (
        'name = "neck_tilt"       # pitch, + = head up\nparent = "neck_pan"',
        'name = "neck_tilt"\nparent = "spine"',
        r"joint\[1\]\.parent: expected a joint of this head",
    ),
    (
        "limits_deg = [-30.0, 30.0]",
        "limits_deg = [30.0, -30.0]",
        r"joint\[1\]\.limits_deg: expected \[lower, upper\] with lower < upper",
    ),
    (
        "servo = { id = 2, model",
        "servo = { id = 1, model",
        r"actuator\[1\]\.servo\.id: expected a servo id not used before",
    ),
    (
        'servo = { id = 3, model = "XL330-M288" }',
        'servo = { id = 3, model = "SG90" }',
        r"actuator\[2\]\.servo\.model: expected one of the known servo models",
    ),
    (
        "pivot_mm = [0.0, 100.0, 5.0]",
        "pivot_mm = [0.0, nan, 5.0]",
        r"joint\[3\]\.pivot_mm\[1\]: expected a finite number",
    ),
    (
        "axis = [0.0, 0.0, 1.0]\nlimits_deg = [-25.0, 25.0]",
        "axis = [0.0, 0.0, 0.0]\nlimits_deg = [-25.0, 25.0]",
        r"joint\[2\]\.axis: expected a non-zero direction",
    ),
    (
        'brow_inner_l = { near_mm = [14.0, 148.0, 87.0], mirror = "brow_inner_r" }',
        'brow_inner_l = { vertex = 999999, mirror = "brow_inner_r" }',
        r"anchors\.brow_inner_l\.vertex: expected a skin vertex index in 0\.\.",
    ),
    (
        'mesh = "builtin:human_jaw"',
        'mesh = "meshes/missing.stl"',
        r"part\[2\]\.mesh: expected an existing mesh file",
    ),
    (
        'mesh = "builtin:human_jaw"',
        'mesh = "builtin:robot_jaw"',
        r"part\[2\]\.mesh: expected a built-in part mesh",
    ),
    (
        'joints = ["jaw"]',
        'joints = ["mandible"]',
        r"actuator\[17\]\.joints\[0\]: expected a joint of this head",
    ),
    (
        'joints = ["jaw"]',
        'joints = ["jaw"]\nrange_deg = [0.0, 40.0]',
        r"actuator\[17\]\.range_deg: expected a range within the joints' limits",
    ),
    (
        'joints = ["neck_roll"]',
        'joints = ["jaw"]',
        r"actuator\[20\]\.joints\[0\]: expected a joint no other actuator drives",
    ),
    (
        'anchor = "nose_wrinkle"',
        'anchor = "nose_tip"',
        r"actuator\[9\]\.anchor: expected an anchor named in \[anchors\]",
    ),
    (
        "line = [0.0, -0.6, -0.8]",
        "line = [0.0, 0.0, 0.0]",
        r"actuator\[9\]\.line: expected a non-zero direction",
    ),
    (
        "range_mm = [0.0, 6.0]",
        "range_mm = [6.0, 0.0]",
        r"actuator\[9\]\.range_mm: expected \[lower, upper\] with lower < upper",
    ),
    (
        'kind = "anchor"\nanchor = "upper_lip"',
        'kind = "cable"\nanchor = "upper_lip"',
        r"actuator\[10\]\.kind: expected \"joint\" or \"anchor\"",
    ),
    (
        'roles = ["lip_corner_l", "lip_depressor_l"]',
        'roles = ["lip_corner_l", "smile"]',
        r"coupling\[0\]\.roles\[1\]: expected an actuator role of this head",
    ),
    ("max_sum_share = 1.5", "max_sum_share = -1.0", r"coupling\[0\]\.max_sum_share: expected a number in"),
    ("rs_mm = 46.0", "rs_mm = 80.0", r"muscle\[0\]\.rf_mm: expected 0 < rs_mm < rf_mm"),
    (
        'type = "sphincter"\ncentre_mm = [0.0, 72.0, 80.0]',
        'type = "ring"\ncentre_mm = [0.0, 72.0, 80.0]',
        r"muscle\[\d+\]\.type: expected one of",
    ),
    (
        "semi_axes_mm = [40.0, 17.0, 20.0]",
        "semi_axes_mm = [30.0]",
        r"muscle\[\d+\]\.semi_axes_mm: expected \[lx, ly\]",
    ),
    (
        'name = "procerus"',
        'name = "corrugator_r"',
        r"muscle\[\d+\]\.name: expected a muscle name not used before",
    ),
    (
        "brow_outer_l = { near_mm = [42.0, 146.0, 78.0]",
        "brow_outer_l = { near_mm = [42.0, 146.0, 178.0]",
        r"anchors\.brow_outer_l\.near_mm: expected a point within 10\.0 mm of the skin",
    ),
    ('face_type = "human"', 'face_type = "cat"', r"face_type: expected one of \['human', 'dog'\]"),
    ("schema_version = 1", "schema_version = 2", r"schema_version: expected 1"),
    (
        'calibration = "calibration.json"',
        'calibraton = "calibration.json"',
        r"calibraton: expected one of the known keys",
    ),
    ('au_table = "builtin"', 'au_table = "tables/none.toml"', r"au_table: expected an existing file"),
    ("smooth_iterations = ", "smooth_iterations = -1  # ", r"skin\.smooth_iterations: expected an integer"),
    (
        'joint = "jaw"\nfalloff_mm',
        'joint = "chin"\nfalloff_mm',
        r"skin\.bind\[0\]\.joint: expected a joint of this head",
    ),
    (
        "color_rgba = [0.22, 0.22, 0.24, 1.0]",
        "color_rgba = [0.22, 0.22, 2.0, 1.0]",
        r"part\[1\]\.color_rgba: expected four numbers in 0\.\.1",
    ),
    (
        'name = "neck_pan"        # yaw',
        'name = "neck_pan"\nparent = "neck_roll"  #',
        r"joint\[\d+\]\.parent: expected a joint tree \(no cycles\)",
    ),
    # positions and lengths far beyond any head (a typo or a wrong unit): refused by name, before a muscle
    # model or a twin squares them to infinity (a pivot at 1e200 mm crashed `check` with an IndexError)
    (
        "pivot_mm = [0.0, 20.0, 0.0]",
        "pivot_mm = [0.0, 1e200, 0.0]",
        r"joint\[1\]\.pivot_mm\[1\]: expected a length within \+-10000 mm",
    ),
    (
        "eye_centre_l = [32.0, 126.0, 66.0]",
        "eye_centre_l = [32.0, 126.0, 66000.0]",
        r"landmarks\.eye_centre_l\[2\]: expected a length within \+-10000 mm",
    ),
    (
        "semi_axes_mm = [40.0, 17.0, 20.0]",
        "semi_axes_mm = [4e4, 17.0, 20.0]",
        r"muscle\[\d+\]\.semi_axes_mm\[0\]: expected a length within \+-10000 mm",
    ),
    (
        "rs_mm = 46.0",
        "rs_mm = -1e300",
        r"muscle\[0\]\.rs_mm: expected a length within \+-10000 mm",
    ),
    # an integer beyond a float's range is not a finite number (float() of it raised OverflowError)
    (
        "limits_deg = [-60.0, 60.0]",
        "limits_deg = [-1" + "0" * 400 + ", 60.0]",
        r"joint\[0\]\.limits_deg\[0\]: expected a finite number",
    ),
]


@pytest.mark.parametrize(("old", "new", "message"), BAD_CASES, ids=[c[2][:40] for c in BAD_CASES])
def test_bad_profiles_name_file_and_key(tmp_path: Path, old: str, new: str, message: str) -> None:
    folder = _copy(tmp_path)
    _edit(folder, old, new)
    with pytest.raises(HeadProfileError, match=message) as info:
        load_profile(folder)
    assert str(folder / "head.toml") in str(info.value)


def test_missing_mesh_is_a_mesh_error(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    _edit(folder, 'mesh = "builtin:human_skin"', 'mesh = "face.stl"')
    with pytest.raises(HeadMeshError, match=r"skin\.mesh: expected an existing mesh file"):
        load_profile(folder)


def test_unreadable_mesh_is_a_mesh_error(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    (folder / "broken.stl").write_bytes(b"solid nothing\nendsolid\n")
    _edit(folder, 'mesh = "builtin:human_jaw"', 'mesh = "broken.stl"')
    with pytest.raises(HeadMeshError, match=r"part\[2\]\.mesh"):
        load_profile(folder)


def test_editing_a_mesh_reloads_the_profile(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    jaw = load_head("human").part("jaw").mesh.copy()
    jaw.export(folder / "jaw.stl")
    _edit(folder, 'mesh = "builtin:human_jaw"', 'mesh = "jaw.stl"')
    first = load_head(folder)
    assert load_head(folder) is first  # cached
    jaw.apply_translation((0.0, 0.0, 5.0))
    jaw.export(folder / "jaw.stl")
    import os

    st = (folder / "jaw.stl").stat()
    os.utime(folder / "jaw.stl", ns=(st.st_atime_ns, st.st_mtime_ns + 10_000_000))
    second = load_head(folder)
    assert second is not first
    assert np.isclose(second.part("jaw").mesh.bounds[1][2], first.part("jaw").mesh.bounds[1][2] + 5.0)


def test_invalid_toml_names_the_file(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    (folder / "head.toml").write_text("name = [unclosed\n")
    with pytest.raises(HeadProfileError, match="not valid TOML"):
        load_profile(folder)


def test_missing_profile_file(tmp_path: Path) -> None:
    with pytest.raises(HeadProfileError, match="head.toml"):
        load_profile(tmp_path)


def test_coupling_rules_and_muscle_mirrors_are_loaded() -> None:
    head = load_head("human")
    rule = head.coupling_rules[0]
    assert rule.roles == ("lip_corner_l", "lip_depressor_l") and rule.max_sum_share == 1.5
    left, right = head.muscle("zygomatic_major_l"), head.muscle("zygomatic_major_r")
    assert right.insertion_mm == (-left.insertion_mm[0], left.insertion_mm[1], left.insertion_mm[2])  # type: ignore[union-attr]
    a_l, a_r = head.actuator("lip_corner_l"), head.actuator("lip_corner_r")
    v_l, v_r = head.skin_vertex_mm(a_l.vertex), head.skin_vertex_mm(a_r.vertex)  # type: ignore[union-attr]
    np.testing.assert_allclose(v_r, v_l * [-1.0, 1.0, 1.0], atol=1e-6)


def test_loaded_heads_are_read_only() -> None:
    head = load_head("human")
    with pytest.raises(ValueError):
        head.skin.vertices_mm[0, 0] = 1.0
    with pytest.raises(AttributeError):
        head.name = "other"  # type: ignore[misc]


def test_a_huge_direction_is_still_a_direction(tmp_path: Path) -> None:
    """A direction is normalised without squaring its components: [-1e200, 0, 0] is the axis [-1, 0, 0] (its
    square overflowed to inf and the axis became [0, 0, 0], which crashed `check` with ZeroDivisionError)."""
    folder = _copy(tmp_path)
    _edit(
        folder,
        "pivot_mm = [0.0, 20.0, 0.0]\naxis = [-1.0, 0.0, 0.0]",
        "pivot_mm = [0.0, 20.0, 0.0]\naxis = [-1e200, 0.0, 0.0]",
    )
    head = load_profile(folder)
    tilt = next(j for j in head.joints if j.name == "neck_tilt")
    assert tilt.axis == (-1.0, 0.0, 0.0)


def test_a_mesh_beyond_ten_metres_is_refused_with_its_scale(tmp_path: Path) -> None:
    """A part mesh in mm given scale = 1000 (as if it were in metres) reaches ~100 m: refused by name."""
    folder = _copy(tmp_path)
    _edit(folder, 'mesh = "builtin:human_jaw"', 'mesh = "builtin:human_jaw"\nscale = 1000.0')
    with pytest.raises(HeadMeshError, match=r"part\[2\]\.mesh: expected vertices within \+-10000 mm .* at scale 1000"):
        load_profile(folder)


def test_a_scale_that_overflows_is_refused_without_a_numpy_warning(tmp_path: Path) -> None:
    """scale = 1e308 makes the jaw's vertices inf: the same refusal by name, and no RuntimeWarning printed."""
    import warnings

    folder = _copy(tmp_path)
    _edit(folder, 'mesh = "builtin:human_jaw"', 'mesh = "builtin:human_jaw"\nscale = 1e308')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(HeadMeshError, match=r"part\[2\]\.mesh: expected vertices within .* reaches inf mm"):
            load_profile(folder)
