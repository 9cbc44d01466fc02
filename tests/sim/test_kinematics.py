"""Forward kinematics, skinning and posed parts, checked against hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from servoface.sim.errors import PoseError
from servoface.sim.head import Head
from servoface.sim.kinematics import (
    joint_angles,
    joint_transforms,
    linear_blend,
    neutral_pose,
    posed_parts,
    posed_skin_vertices,
    rotation_about_axis,
)
from servoface.sim.rig import HeadPose, Joint, RigidPart, Skin


def _toy_head() -> Head:
    """Two joints: a yaw at the origin and a pitch about +x through (0, 10, 0), child of the yaw."""
    joints = (
        Joint("yaw", None, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), -90.0, 90.0),
        Joint("pitch", "yaw", (0.0, 10.0, 0.0), (1.0, 0.0, 0.0), -45.0, 45.0),
    )
    verts = np.array([[0.0, 10.0, 5.0], [0.0, 0.0, 5.0], [1.0, 0.0, 0.0]])
    weights = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, 0.5, 0.5]])
    skin = Skin(verts, np.array([[0, 1, 2]]), ("yaw", "pitch"), weights)
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    box.apply_translation((0.0, 10.0, 5.0))
    parts = (RigidPart("tip", "pitch", box), RigidPart("base", None, box.copy()))
    return Head("toy", "human", joints, parts, skin, (), ())


def test_rotation_about_x_by_90_maps_y_to_z() -> None:
    r = rotation_about_axis(np.array([[1.0, 0.0, 0.0]]), np.array([math.pi / 2]))[0]
    np.testing.assert_allclose(r @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-12)


def test_rotation_about_an_axis_through_a_pivot() -> None:
    head = _toy_head()
    tf = joint_transforms(head, {"pitch": 90.0 * 0.5})  # 45 deg about +x through (0, 10, 0)
    p = np.array([0.0, 10.0, 5.0, 1.0])  # 5 mm in front of the pivot
    out = tf["pitch"] @ p
    s = math.sin(math.radians(45.0)) * 5.0
    np.testing.assert_allclose(out[:3], [0.0, 10.0 - s, s], atol=1e-9)  # +x rotation turns +z towards -y
    np.testing.assert_allclose(tf["pitch"] @ [0.0, 10.0, 0.0, 1.0], [0.0, 10.0, 0.0, 1.0], atol=1e-12)


def test_child_joint_composes_with_its_parent() -> None:
    head = _toy_head()
    tf = joint_transforms(head, {"yaw": 90.0, "pitch": 0.0})
    # yaw 90 about +y: +z goes to +x; the child's point in front of its pivot follows the parent
    np.testing.assert_allclose(tf["pitch"] @ [0.0, 10.0, 5.0, 1.0], [5.0, 10.0, 0.0, 1.0], atol=1e-9)
    both = joint_transforms(head, {"yaw": 90.0, "pitch": 30.0})
    expected = both["yaw"] @ joint_transforms(head, {"pitch": 30.0})["pitch"]
    np.testing.assert_allclose(both["pitch"], expected, atol=1e-12)


def test_angles_are_clamped_to_the_joint_limits() -> None:
    head = _toy_head()
    beyond = joint_transforms(head, {"pitch": 80.0})["pitch"]
    at_limit = joint_transforms(head, {"pitch": 45.0})["pitch"]
    np.testing.assert_allclose(beyond, at_limit)
    q = joint_angles(head, {"yaw": -500.0, "pitch": 10.0})
    assert list(q) == [-90.0, 10.0]


def test_builtin_joint_limits_are_respected(head: Head) -> None:
    wild = {j.name: j.upper_deg + 100.0 for j in head.joints}
    q = joint_angles(head, wild)
    assert np.all(q == np.array([j.upper_deg for j in head.joints]))


@pytest.mark.parametrize("bad", [{"nope": 1.0}, {"jaw": float("nan")}, {"jaw": float("inf")}])
def test_bad_joint_angles_raise(head: Head, bad: dict[str, float]) -> None:
    with pytest.raises(PoseError, match="nope|finite"):
        joint_transforms(head, bad)


def test_linear_blend_skinning_mixes_the_transforms() -> None:
    head = _toy_head()
    pose = HeadPose({"yaw": 0.0, "pitch": 90.0 / 2}, np.zeros((3, 3)))
    out = posed_skin_vertices(head, pose)
    tf = joint_transforms(head, pose.joint_deg)
    np.testing.assert_allclose(out[0], (tf["pitch"] @ [0.0, 10.0, 5.0, 1.0])[:3], atol=1e-12)
    np.testing.assert_allclose(out[1], [0.0, 0.0, 5.0], atol=1e-12)  # yaw at 0: unmoved
    half = 0.5 * (tf["yaw"] @ [1.0, 0.0, 0.0, 1.0]) + 0.5 * (tf["pitch"] @ [1.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(out[2], half[:3], atol=1e-12)


def test_skin_offsets_are_applied_before_skinning() -> None:
    head = _toy_head()
    offsets = np.zeros((3, 3))
    offsets[0] = [0.0, 0.0, 1.0]
    pose = HeadPose({"yaw": 90.0}, offsets)
    out = posed_skin_vertices(head, pose)
    np.testing.assert_allclose(out[0], [6.0, 10.0, 0.0], atol=1e-9)  # (0, 10, 6) turned to +x


def test_skin_offsets_of_the_wrong_shape_raise(head: Head) -> None:
    pose = neutral_pose(head)
    pose.skin_offset_mm = np.zeros((3, 3))
    with pytest.raises(PoseError, match="shape"):
        posed_skin_vertices(head, pose)


def test_neutral_pose_leaves_everything_at_rest(head: Head) -> None:
    pose = neutral_pose(head)
    assert set(pose.joint_deg) == set(head.joint_names)
    assert set(pose.actuator_targets) == set(head.roles)
    np.testing.assert_allclose(posed_skin_vertices(head, pose), head.skin.vertices_mm, atol=1e-9)
    for p in posed_parts(head, pose):
        np.testing.assert_allclose(p.mesh.vertices, head.part(p.name).mesh.vertices, atol=1e-9)


def test_posed_parts_follow_their_joint_and_leave_rest_meshes_alone(head: Head) -> None:
    pose = neutral_pose(head)
    pose.joint_deg["eye_pan_l"] = 30.0
    rest_before = np.array(head.part("pupil_l").mesh.vertices)
    parts = {p.name: p for p in posed_parts(head, pose)}
    pupil = parts["pupil_l"].mesh.vertices.mean(0)
    centre = np.asarray(head.landmarks_mm["eye_centre_l"])
    assert pupil[0] > centre[0] + 4.0  # + pan turns the eye to the head's left (+x)
    np.testing.assert_allclose(parts["pupil_r"].mesh.vertices, head.part("pupil_r").mesh.vertices)
    np.testing.assert_allclose(head.part("pupil_l").mesh.vertices, rest_before)
    assert np.allclose(parts["eyeball_l"].transform, joint_transforms(head, pose.joint_deg)["eye_tilt_l"])


def test_neck_moves_the_whole_head_rigidly(head: Head) -> None:
    pose = neutral_pose(head)
    pose.joint_deg["neck_pan"] = 40.0
    out = posed_skin_vertices(head, pose)
    r = rotation_about_axis(np.array([[0.0, 1.0, 0.0]]), np.array([math.radians(40.0)]))[0]
    np.testing.assert_allclose(out, head.skin.vertices_mm @ r.T, atol=1e-9)


def test_linear_blend_matches_a_loop() -> None:
    rng = np.random.default_rng(0)
    v = rng.normal(size=(20, 3))
    w = rng.random((20, 3))
    w /= w.sum(1, keepdims=True)
    tfs = np.stack([np.eye(4)] * 3)
    for k in range(3):
        tfs[k, :3, :3] = rotation_about_axis(np.array([[0.0, 0.0, 1.0]]), np.array([0.3 * k]))[0]
        tfs[k, :3, 3] = [k, 0, 0]
    expected = np.array([sum(w[i, k] * (tfs[k] @ np.append(v[i], 1.0))[:3] for k in range(3)) for i in range(20)])
    np.testing.assert_allclose(linear_blend(v, w, tfs), expected, atol=1e-12)


def test_clamp_to_limits_reports_the_reachable_angles(head: Head) -> None:
    from servoface.sim.kinematics import clamp_to_limits

    assert clamp_to_limits(head, {"jaw": 90.0, "eye_pan_l": -10.0}) == {"jaw": 25.0, "eye_pan_l": -10.0}


def test_head_lookups_name_what_exists(head: Head) -> None:
    assert head.joint("jaw").parent == "neck_roll"
    assert head.actuator("jaw").servo.id == 18
    assert head.servo_ids["lip_corner_l"] == 12
    with pytest.raises(KeyError, match="joints"):
        head.joint("tail")
    with pytest.raises(KeyError, match="roles"):
        head.actuator("tail")
    with pytest.raises(KeyError, match="parts"):
        head.part("tail")
