"""The built-in heads: they load, are deterministic, symmetric, consistent, and the jaw opens the mouth."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.head import Head
from servoface.sim.heads import load_head
from servoface.sim.kinematics import neutral_pose, posed_parts, posed_skin_vertices
from servoface.sim.rig import SERVO_MODELS, AnchorActuator, JointActuator

HUMAN_ROLES = [
    "brow_inner_l", "brow_inner_r", "brow_outer_l", "brow_outer_r", "upper_lid_l", "upper_lid_r",
    "lower_lid_l", "eye_pan_l", "eye_tilt", "nose_wrinkle", "upper_lip", "lip_corner_l", "lip_corner_r",
    "lip_depressor_l", "lip_depressor_r", "lower_lip", "lip_pucker", "jaw", "neck_pan", "neck_tilt",
    "neck_roll", "lower_lid_r", "eye_pan_r", "cheek_l", "cheek_r", "chin", "brow_knit_l", "brow_knit_r",
    "corner_stretch_l", "corner_stretch_r",
]  # fmt: skip
DOG_ROLES = [
    "lip_raise_l", "lip_raise_r", "mouth_corner_l", "mouth_corner_r", "nostrils", "upper_lid_l",
    "upper_lid_r", "ear_pan_l", "ear_pan_r", "ear_tilt_l", "ear_tilt_r", "jaw", "jaw_lateral",
    "neck_pitch", "neck_yaw", "neck_roll", "eye_pan", "eye_tilt", "tongue_extend", "tongue_tip", "brow_l",
    "brow_r", "forehead_l", "forehead_r", "ear_root_l", "ear_root_r", "nostril_wing_l", "nostril_wing_r",
    "muzzle",
]  # fmt: skip
HUMAN_MUSCLES = [
    "frontalis_medial_l", "frontalis_medial_r", "frontalis_lateral_l", "frontalis_lateral_r", "corrugator_l",
    "corrugator_r", "procerus", "orbicularis_oculi_l", "orbicularis_oculi_r", "levator_labii_alaeque_l",
    "levator_labii_alaeque_r", "levator_labii_l", "levator_labii_r", "zygomatic_major_l", "zygomatic_major_r",
    "buccinator_l", "buccinator_r", "depressor_anguli_l", "depressor_anguli_r", "depressor_labii_l",
    "depressor_labii_r", "mentalis", "risorius_l", "risorius_r", "orbicularis_oris",
    "brow_depressor_l", "brow_depressor_r",  # issue 11: AU4 lowers the outer brow too
]  # fmt: skip
DOG_MUSCLES = [
    "levator_nasolabialis_l", "levator_nasolabialis_r", "zygomaticus_l", "zygomaticus_r", "levator_nasi",
    "nostril_dilator_l", "nostril_dilator_r", "orbicularis_oris", "levator_anguli_oculi_l",
    "levator_anguli_oculi_r", "frontalis_l", "frontalis_r", "auricularis_rostralis_l",
    "auricularis_rostralis_r",
]  # fmt: skip
HUMAN_JOINTS = [
    "neck_pan", "neck_tilt", "neck_roll", "jaw", "eye_pan_l", "eye_pan_r", "eye_tilt_l", "eye_tilt_r",
    "upper_lid_l", "upper_lid_r", "lower_lid_l", "lower_lid_r",
]  # fmt: skip
DOG_JOINTS = [
    "neck_pitch", "neck_yaw", "neck_roll", "jaw", "jaw_lateral", "eye_pan_l", "eye_pan_r", "eye_tilt_l",
    "eye_tilt_r", "upper_lid_l", "upper_lid_r", "ear_pan_l", "ear_pan_r", "ear_tilt_l", "ear_tilt_r",
    "tongue_extend", "tongue_tip",
]  # fmt: skip
HUMAN_PARTS = [
    "skull",
    "neck",
    "jaw",
    "eyeball_l",
    "eyeball_r",
    "upper_lid_l",
    "upper_lid_r",
    "lower_lid_l",
    "lower_lid_r",
]
DOG_PARTS = [
    "skull",
    "neck",
    "jaw",
    "eyeball_l",
    "eyeball_r",
    "upper_lid_l",
    "upper_lid_r",
    "ear_l",
    "ear_r",
    "tongue_root",
    "tongue_tip",
]

CONTRACT = {
    "human": (HUMAN_ROLES, HUMAN_MUSCLES, HUMAN_JOINTS, HUMAN_PARTS),
    "dog": (DOG_ROLES, DOG_MUSCLES, DOG_JOINTS, DOG_PARTS),
}


@pytest.fixture(params=["human", "dog"])
def any_head(request: pytest.FixtureRequest) -> Head:
    return load_head(request.param)


def test_builtins_follow_the_face_contract(any_head: Head) -> None:
    roles, muscles, joints, parts = CONTRACT[any_head.name]
    assert any_head.face_type == any_head.name
    assert list(any_head.roles) == roles
    assert sorted(m.name for m in any_head.muscles) == sorted(muscles)
    assert sorted(any_head.joint_names) == sorted(joints)
    assert set(parts) <= {p.name for p in any_head.parts}
    assert [a.servo.id for a in any_head.actuators] == list(range(1, len(roles) + 1))
    assert all(a.servo.model in SERVO_MODELS for a in any_head.actuators)
    assert any_head.calibration_path is not None and any_head.calibration_path.name == "calibration.json"
    assert any_head.profile_dir is not None and (any_head.profile_dir / "head.toml").is_file()


def test_skin_is_a_usable_mesh(any_head: Head) -> None:
    skin = any_head.skin
    n = len(skin.vertices_mm)
    assert 2000 <= n <= 6500
    assert skin.faces.min() >= 0 and skin.faces.max() < n
    assert np.all(np.isfinite(skin.vertices_mm))
    np.testing.assert_allclose(skin.weights.sum(1), 1.0, atol=1e-9)
    assert skin.weights.shape == (n, len(skin.joint_names) + 1)
    assert skin.vertex_colors_rgba is not None and skin.vertex_colors_rgba.shape == (n, 4)
    tri = skin.vertices_mm[skin.faces]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    assert area.min() > 1e-6, "degenerate skin triangles"


def test_every_actuator_names_existing_joints_or_vertices(any_head: Head) -> None:
    names = set(any_head.joint_names)
    for a in any_head.actuators:
        if isinstance(a, JointActuator):
            assert set(a.joints) <= names
            for j in a.joints:
                jt = any_head.joint(j)
                assert jt.lower_deg <= a.lower_deg < a.upper_deg <= jt.upper_deg
        else:
            assert isinstance(a, AnchorActuator)
            assert 0 <= a.vertex < any_head.n_skin_vertices
            assert np.isclose(np.linalg.norm(a.line), 1.0)


def test_anchor_vertices_sit_where_the_profile_says(any_head: Head) -> None:
    # anchors are given by near_mm; the chosen vertex must be close to the face surface point asked for
    for a in any_head.anchor_actuators:
        v = any_head.skin_vertex_mm(a.vertex)
        assert v[2] > 40.0, f"{a.role}: anchor vertex {v} is not on the face"


_DIGEST = """
import hashlib, numpy as np
from servoface.sim.heads import builtin
h = hashlib.sha256()
for name in sorted(builtin.SKIN_MESHES):
    for arr in builtin.SKIN_MESHES[name]():
        h.update(np.ascontiguousarray(arr).tobytes())
for name in sorted(builtin.PART_MESHES):
    for arr in builtin.PART_MESHES[name]():
        h.update(np.ascontiguousarray(arr).tobytes())
print(h.hexdigest())
"""


def test_builtin_meshes_are_deterministic() -> None:
    """Two fresh processes generate the same bytes for every built-in mesh (no caches shared)."""
    import subprocess
    import sys

    runs = [
        subprocess.run([sys.executable, "-c", _DIGEST], capture_output=True, text=True, check=True).stdout
        for _ in range(2)
    ]
    assert len(runs[0].strip()) == 64 and runs[0] == runs[1]


def _mirror_match(points: np.ndarray, tol: float) -> float:
    from scipy.spatial import cKDTree

    mirrored = points * np.array([-1.0, 1.0, 1.0])
    d, _ = cKDTree(points).query(mirrored)
    return float(d.max())


def test_builtins_are_left_right_symmetric(any_head: Head) -> None:
    assert _mirror_match(any_head.skin.vertices_mm, 1e-6) < 1e-6
    parts = {p.name: p for p in any_head.parts}
    for name, part in parts.items():
        twin = name[:-2] + {"_l": "_r", "_r": "_l"}.get(name[-2:], name[-2:])
        other = parts.get(twin, part)
        a = np.asarray(part.mesh.vertices) * np.array([-1.0, 1.0, 1.0])
        from scipy.spatial import cKDTree

        d, _ = cKDTree(np.asarray(other.mesh.vertices)).query(a)
        assert d.max() < 1e-6, f"part {name} is not the mirror of {twin}"
    for j in any_head.joints:
        if j.name.endswith("_l"):
            r = any_head.joint(j.name[:-2] + "_r")
            assert np.allclose(r.pivot_mm, (-j.pivot_mm[0], j.pivot_mm[1], j.pivot_mm[2]))
            mirrored_axis = np.array([j.axis[0], -j.axis[1], -j.axis[2]])
            # mirror-image motion (ears) or the same motion for both (gaze, lids)
            assert np.allclose(r.axis, mirrored_axis) or np.allclose(r.axis, j.axis)
            assert (r.lower_deg, r.upper_deg) == (j.lower_deg, j.upper_deg)


def test_jaw_region_follows_the_jaw_and_the_mouth_opens(any_head: Head) -> None:
    pose = neutral_pose(any_head)
    rest = posed_skin_vertices(any_head, pose)
    pose.joint_deg["jaw"] = 20.0
    opened = posed_skin_vertices(any_head, pose)
    moved = np.linalg.norm(opened - rest, axis=1)
    chin = np.asarray(any_head.landmarks_mm["mouth_centre" if any_head.name == "human" else "mouth_front"])
    # the lower-lip copy of the mouth centre moves down by a lot, the upper lip copy stays
    contact = rest[np.argmin(np.linalg.norm(rest - chin, axis=1))]
    near = np.nonzero(np.linalg.norm(rest - contact, axis=1) < 1e-9)[0]
    assert len(near) == 2, "the mouth line is a slit: two vertices share the lip contact point"
    assert sorted(np.round(moved[near]))[0] < 0.5 and moved[near].max() > 15.0
    lower = near[np.argmax(moved[near])]
    assert opened[lower, 1] < rest[lower, 1] - 10.0
    # the skin above the eyes (almost) does not move with the jaw
    eye = np.asarray(any_head.landmarks_mm["eye_centre_l"])
    above = rest[:, 1] > eye[1] + 10.0
    assert moved[above].max() < 0.5
    # jaw-region skin follows the jaw part: the jaw's weight column is ~1 near the chin
    col = 1 + list(any_head.skin.joint_names).index("jaw" if any_head.name == "human" else "jaw_lateral")
    assert any_head.skin.weights[lower, col] > 0.9


def test_lids_cover_the_eye_when_closed(any_head: Head) -> None:
    pose = neutral_pose(any_head)
    eye = np.asarray(any_head.landmarks_mm["eye_centre_l"])
    gaze = np.asarray(any_head.part("pupil_l").mesh.vertices).mean(0) - eye
    gaze /= np.linalg.norm(gaze)
    upper = any_head.joint("upper_lid_l").upper_deg
    for lid_deg, covered in ((0.0, False), (upper, True)):
        pose.joint_deg["upper_lid_l"] = lid_deg
        parts = {p.name: p for p in posed_parts(any_head, pose)}
        assert _ray_hits(parts["upper_lid_l"].mesh, eye + 60.0 * gaze, -gaze) is covered


def test_eyes_and_lids_turn_about_the_eye_centre(any_head: Head) -> None:
    for side in ("l", "r"):
        centre = np.asarray(any_head.part(f"eyeball_{side}").mesh.vertices).mean(0)
        for j in (f"eye_pan_{side}", f"eye_tilt_{side}", f"upper_lid_{side}"):
            np.testing.assert_allclose(any_head.joint(j).pivot_mm, centre, atol=1e-6)
        np.testing.assert_allclose(any_head.landmarks_mm[f"eye_centre_{side}"], centre, atol=1e-6)


def _ray_hits(mesh: object, origin: np.ndarray, direction: np.ndarray) -> bool:
    """Moller-Trumbore against every triangle (no rtree needed)."""
    tri = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]  # type: ignore[attr-defined]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - tri[:, 0]
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ direction) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    return bool(np.any(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)))


def test_rigid_parts_do_not_collide_at_rest(any_head: Head) -> None:
    import trimesh

    manager = trimesh.collision.CollisionManager()
    for p in posed_parts(any_head, neutral_pose(any_head)):
        if p.collides:
            manager.add_object(p.name, p.mesh)
    hit, pairs = manager.in_collision_internal(return_names=True)
    assert not hit, f"parts collide at rest: {sorted(pairs)}"


def test_parts_have_distinct_colours_for_rendering(any_head: Head) -> None:
    colours = {p.name: p.color_rgba for p in any_head.parts}
    assert colours["eyeball_l"] != colours["iris_l"] != colours["pupil_l"]
    assert colours["eyeball_l"] != colours["upper_lid_l"]
