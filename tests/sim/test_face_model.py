"""FaceModel on a small synthetic human-like face (grid skin, every contract muscle, joint and actuator).

The synthetic head keeps these tests independent of the procedural built-in heads; the built-in heads
are tested in test_face_model_builtin.py.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.sim.errors import ActionUnitValueError, HeadProfileError, SimError, UnknownActionUnitError
from servoface.sim.expressions import load_library
from servoface.sim.face_model import FaceModel
from servoface.sim.muscles import LinearMuscle, SphincterMuscle
from servoface.sim.rig import AnchorActuator, Joint, JointActuator, ServoRef, Skin


def _z(x: float, y: float) -> float:
    return 90.0 - x * x / 120.0


def _p(x: float, y: float, depth: float = 0.0) -> tuple[float, float, float]:
    return (x, y, _z(x, y) - depth)


def _linear(name: str, ap: tuple[float, float], ip: tuple[float, float], zone: float = 35.0) -> LinearMuscle:
    length = math.dist(ap, ip)
    return LinearMuscle(name, _p(*ap, 4.0), _p(*ip), zone, length, 1.3 * length, 0.2)


def synthetic_human(spacing_mm: float = 4.0) -> Any:
    """A flat-ish human face on a grid with the contract's muscles, joints and actuators."""
    xs = np.arange(-72.0, 72.0 + 1e-9, spacing_mm)
    ys = np.arange(20.0, 200.0 + 1e-9, spacing_mm)
    gx, gy = np.meshgrid(xs, ys)
    verts = np.c_[gx.ravel(), gy.ravel(), 90.0 - gx.ravel() ** 2 / 120.0]
    nx = xs.size
    faces = []
    for j in range(ys.size - 1):
        for i in range(nx - 1):
            a = j * nx + i
            faces += [(a, a + 1, a + nx), (a + 1, a + nx + 1, a + nx)]
    muscles: list[Any] = []
    for s, tag in ((1.0, "l"), (-1.0, "r")):
        muscles += [
            _linear(f"frontalis_medial_{tag}", (12 * s, 190), (12 * s, 146), 25),
            _linear(f"frontalis_lateral_{tag}", (40 * s, 190), (40 * s, 146), 25),
            _linear(f"corrugator_{tag}", (4 * s, 134), (24 * s, 146), 30),
            _linear(f"brow_depressor_{tag}", (46 * s, 124), (40 * s, 146), 25),
            _linear(f"levator_labii_alaeque_{tag}", (14 * s, 130), (12 * s, 94), 25),
            _linear(f"levator_labii_{tag}", (26 * s, 118), (14 * s, 80), 25),
            _linear(f"zygomatic_major_{tag}", (56 * s, 112), (24 * s, 72), 30),
            _linear(f"buccinator_{tag}", (52 * s, 74), (25 * s, 72), 25),
            _linear(f"depressor_anguli_{tag}", (36 * s, 38), (24 * s, 70), 25),
            _linear(f"depressor_labii_{tag}", (16 * s, 38), (10 * s, 66), 20),
            _linear(f"risorius_{tag}", (60 * s, 70), (24 * s, 72), 20),
            SphincterMuscle(f"orbicularis_oculi_{tag}", _p(32 * s, 126), (22.0, 16.0, 20.0), 0.2),
        ]
    muscles += [
        _linear("procerus", (0, 112), (0, 140), 25),
        _linear("mentalis", (0, 36), (0, 62), 25),
        SphincterMuscle("orbicularis_oris", _p(0, 72), (30.0, 16.0, 25.0), 0.3),
    ]
    joints = [
        Joint("neck_pan", None, (0, 0, 0), (0, 1, 0), -60, 60),
        Joint("neck_tilt", "neck_pan", (0, 10, 0), (-1, 0, 0), -30, 30),
        Joint("neck_roll", "neck_tilt", (0, 20, 0), (0, 0, 1), -25, 25),
        Joint("jaw", "neck_roll", (0, 100, 5), (1, 0, 0), 0, 25),
    ]
    for s, tag in ((1.0, "l"), (-1.0, "r")):
        eye = (32.0 * s, 126.0, 66.0)
        joints += [
            Joint(f"eye_pan_{tag}", "neck_roll", eye, (0, 1, 0), -35, 35),
            Joint(f"eye_tilt_{tag}", f"eye_pan_{tag}", eye, (-1, 0, 0), -25, 25),
            Joint(f"upper_lid_{tag}", "neck_roll", eye, (1, 0, 0), -15, 55),
            Joint(f"lower_lid_{tag}", "neck_roll", eye, (-1, 0, 0), 0, 25),
        ]

    def vertex(x: float, y: float) -> int:
        return int(np.argmin(np.linalg.norm(verts[:, :2] - (x, y), axis=1)))

    def anchor(role: str, sid: int, x: float, y: float, line: tuple[float, float, float]) -> AnchorActuator:
        n = math.sqrt(sum(c * c for c in line))
        return AnchorActuator(
            role,
            ServoRef(sid, "XL330-M288"),
            vertex(x, y),
            (line[0] / n, line[1] / n, line[2] / n),
            -12.0,
            12.0,
        )

    def joint_act(role: str, sid: int, names: tuple[str, ...]) -> JointActuator:
        j = next(j for j in joints if j.name == names[0])
        return JointActuator(role, ServoRef(sid, "XL330-M288"), names, j.lower_deg, j.upper_deg)

    actuators = [
        anchor("brow_inner_l", 1, 12, 146, (0, 1, 0)),
        anchor("brow_inner_r", 2, -12, 146, (0, 1, 0)),
        anchor("brow_outer_l", 3, 40, 146, (0, 1, 0)),
        anchor("brow_outer_r", 4, -40, 146, (0, 1, 0)),
        joint_act("upper_lid_l", 5, ("upper_lid_l",)),
        joint_act("upper_lid_r", 6, ("upper_lid_r",)),
        joint_act("lower_lids", 7, ("lower_lid_l", "lower_lid_r")),
        joint_act("eye_pan", 8, ("eye_pan_l", "eye_pan_r")),
        joint_act("eye_tilt", 9, ("eye_tilt_l", "eye_tilt_r")),
        anchor("nose_wrinkle", 10, 0, 112, (0, 1, 0)),
        anchor("upper_lip", 11, 0, 80, (0, 1, 0)),
        anchor("lip_corner_l", 12, 24, 72, (0.6, 0.8, -0.1)),
        anchor("lip_corner_r", 13, -24, 72, (-0.6, 0.8, -0.1)),
        anchor("lip_depressor_l", 14, 22, 66, (0, -1, 0)),
        anchor("lip_depressor_r", 15, -22, 66, (0, -1, 0)),
        anchor("lower_lip", 16, 0, 64, (0, -1, 0)),
        anchor("lip_pucker", 17, 14, 76, (-1, 0, 0)),
        joint_act("jaw", 18, ("jaw",)),
        joint_act("neck_pan", 19, ("neck_pan",)),
        joint_act("neck_tilt", 20, ("neck_tilt",)),
        joint_act("neck_roll", 21, ("neck_roll",)),
    ]
    weights = np.zeros((verts.shape[0], len(joints) + 1))
    weights[:, 0] = 1.0
    skin = Skin(verts, np.asarray(faces, dtype=np.int64), tuple(j.name for j in joints), weights)
    return SimpleNamespace(
        name="synthetic_human",
        face_type="human",
        joints=tuple(joints),
        skin=skin,
        muscles=tuple(muscles),
        actuators=tuple(actuators),
        au_table_path=None,
    )


@pytest.fixture(scope="module")
def model() -> FaceModel:
    return FaceModel(synthetic_human())


def _vertex(model: FaceModel, x: float, y: float) -> int:
    v = model.head.skin.vertices_mm
    return int(np.argmin(np.linalg.norm(v[:, :2] - (x, y), axis=1)))


def test_neutral_is_the_rest_face(model: FaceModel) -> None:
    pose = model.solve({})
    assert np.all(pose.skin_offset_mm == 0.0)
    assert pose.joint_deg == {name: 0.0 for name in model.joint_names}
    assert set(pose.actuator_targets) == set(model.roles)
    assert all(v == 0.0 for v in pose.actuator_targets.values())


def test_every_joint_is_in_the_pose(model: FaceModel) -> None:
    pose = model.solve({"AU12": 0.5, "AU26": 1.0})
    assert set(pose.joint_deg) == set(model.joint_names)
    assert pose.skin_offset_mm.shape == (model.n_vertices, 3)
    assert pose.joint_deg["jaw"] == pytest.approx(15.0)
    assert pose.actuator_targets["jaw"] == pytest.approx(15.0)


def test_au12_left_pulls_only_the_left_corner_up_and_out(model: FaceModel) -> None:
    pose = model.solve({"AU12L": 1.0})
    left, right = _vertex(model, 24, 72), _vertex(model, -24, 72)
    assert pose.skin_offset_mm[left, 1] > 1.0  # up
    assert pose.skin_offset_mm[left, 0] > 0.5  # towards the head's left (outwards)
    assert np.allclose(pose.skin_offset_mm[right], 0.0)
    assert pose.actuator_targets["lip_corner_l"] > 1.0
    assert pose.actuator_targets["lip_corner_r"] == 0.0


def test_bilateral_au_drives_both_sides_like_the_pair(model: FaceModel) -> None:
    both = model.solve({"AU12": 0.7})
    pair = model.solve({"AU12L": 0.7, "AU12R": 0.7})
    assert np.allclose(both.skin_offset_mm, pair.skin_offset_mm)
    assert both.actuator_targets["lip_corner_l"] == pytest.approx(both.actuator_targets["lip_corner_r"])


def test_anchor_target_is_the_projected_displacement(model: FaceModel) -> None:
    pose = model.solve({"AU1": 0.8, "AU15": 0.6})
    for act in model.anchor_actuators:
        expected = float(np.dot(pose.skin_offset_mm[act.vertex], act.line))
        assert pose.actuator_targets[act.role] == pytest.approx(expected)
    assert pose.actuator_targets["brow_inner_l"] > 0.5
    assert pose.actuator_targets["lip_depressor_l"] > 0.3


def test_brow_antagonists_sum_then_cancel(model: FaceModel) -> None:
    up = model.solve({"AU1": 0.5}).actuator_targets["brow_inner_l"]
    down = model.solve({"AU4": 1.0}).actuator_targets["brow_inner_l"]
    both = model.solve({"AU1": 0.5, "AU4": 1.0}).actuator_targets["brow_inner_l"]
    assert 0.5 < up < 12.0 and -12.0 < down < -0.3  # inside the actuator range: no clamp
    assert both == pytest.approx(up + down, abs=1e-9)  # displacements sum (from rest)


def test_lid_antagonists_blink_wins_over_wide_open(model: FaceModel) -> None:
    assert model.solve({"AU5": 1.0}).joint_deg["upper_lid_l"] == pytest.approx(-15.0)
    both = model.solve({"AU5": 1.0, "AU45": 1.0})
    assert both.joint_deg["upper_lid_l"] == pytest.approx(55.0)  # summed then clamped to the lid stop
    assert both.actuator_targets["upper_lid_r"] == pytest.approx(55.0)


def test_mouth_corner_antagonists_partly_cancel(model: FaceModel) -> None:
    smile = model.solve({"AU12": 1.0}).skin_offset_mm
    frown = model.solve({"AU15": 1.0}).skin_offset_mm
    both = model.solve({"AU12": 1.0, "AU15": 1.0}).skin_offset_mm
    assert np.allclose(both, smile + frown)


def test_contractions_are_clamped_to_the_limit(model: FaceModel) -> None:
    # AU12 (1.0), AU13 (0.7) and AU6 (0.15 assist) all drive zygomatic major: the sum clamps at 1.
    sol = model.solve_detailed({"AU12": 1.0, "AU13": 1.0, "AU6": 1.0})
    assert sol.contractions["zygomatic_major_l"] == pytest.approx(1.0)
    corner = _vertex(model, 24, 72)
    naive = sum(model.solve({au: 1.0}).skin_offset_mm[corner] for au in ("AU12", "AU13", "AU6"))
    assert np.linalg.norm(sol.pose.skin_offset_mm[corner]) < np.linalg.norm(naive) - 1.0


@pytest.mark.parametrize(
    ("aus", "error", "words"),
    [
        ({"AU99": 0.5}, UnknownActionUnitError, ["AU99", "known"]),
        ({"AU26L": 0.5}, UnknownActionUnitError, ["AU26L", "left/right"]),
        ({"smile": 0.5}, UnknownActionUnitError, ["smile", "AU12"]),
        ({"AU12": float("nan")}, ActionUnitValueError, ["AU12", "[0.0, 1.0]"]),
        ({"AU12": 1.5}, ActionUnitValueError, ["AU12", "[0.0, 1.0]"]),
        ({"AU12": -0.2}, ActionUnitValueError, ["AU12", "no counter"]),
        ({"AU12": "0.5"}, ActionUnitValueError, ["AU12", "number"]),
        ({"AU12": True}, ActionUnitValueError, ["AU12"]),
    ],
)
def test_bad_aus_raise_typed_errors_and_change_nothing(
    model: FaceModel, aus: dict[str, Any], error: type[Exception], words: list[str]
) -> None:
    before = model.solve({"AU12": 0.5})
    with pytest.raises(error) as info:
        model.solve({"AU1": 0.3, **aus})
    for word in words:
        assert word in str(info.value)
    after = model.solve({"AU12": 0.5})
    assert np.array_equal(before.skin_offset_mm, after.skin_offset_mm)
    assert before.actuator_targets == after.actuator_targets


def test_every_library_expression_solves_and_differs(model: FaceModel) -> None:
    library = load_library("human")
    poses = {name: model.solve(e.apex()) for name, e in library.items()}
    names = sorted(poses)

    def signature(name: str) -> np.ndarray:
        pose = poses[name]
        joints = np.array([pose.joint_deg[j] for j in model.joint_names])
        return np.concatenate([pose.skin_offset_mm.ravel(), joints])

    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert np.abs(signature(a) - signature(b)).max() > 1.0, (a, b)


def test_twin_reproduces_joint_and_anchor_targets_exactly(model: FaceModel) -> None:
    for aus in ({"AU12": 1.0, "AU6": 0.6}, {"AU1": 0.8, "AU4": 0.3, "AU26": 0.5}, {"AU9": 1.0, "AU16": 0.5}):
        pose = model.solve(aus)
        twin = model.pose_from_targets(pose.actuator_targets)
        for act in model.anchor_actuators:
            got = float(np.dot(twin.skin_offset_mm[act.vertex], act.line))
            assert got == pytest.approx(pose.actuator_targets[act.role], abs=1e-6), act.role
        for name in ("jaw", "upper_lid_l", "neck_pan"):
            assert twin.joint_deg[name] == pytest.approx(pose.joint_deg[name])


def test_twin_face_looks_like_the_muscle_face(model: FaceModel) -> None:
    for aus in ({"AU12": 1.0}, {"AU15": 1.0, "AU17": 0.5}, {"AU1": 0.8}):
        pose = model.solve(aus)
        twin = model.pose_from_targets(pose.actuator_targets)
        err = np.linalg.norm(twin.skin_offset_mm - pose.skin_offset_mm, axis=1)
        size = np.linalg.norm(pose.skin_offset_mm, axis=1)
        assert size.max() > 2.0
        assert err.max() < 0.35 * size.max(), aus
    # far from every anchor and muscle the twin leaves the skin alone
    assert np.allclose(twin.skin_offset_mm[_vertex(model, 0, 196)], 0.0)


def test_twin_missing_roles_sit_at_neutral_and_bad_roles_raise(model: FaceModel) -> None:
    twin = model.pose_from_targets({"jaw": 10.0})
    assert twin.joint_deg["jaw"] == pytest.approx(10.0)
    assert np.allclose(twin.skin_offset_mm, 0.0)
    assert twin.actuator_targets["brow_inner_l"] == 0.0
    with pytest.raises(SimError, match="tail"):
        model.pose_from_targets({"tail": 1.0})
    with pytest.raises(SimError, match="jaw"):
        model.pose_from_targets({"jaw": float("inf")})


_MODEL = None


def _shared_model() -> FaceModel:
    global _MODEL
    if _MODEL is None:
        _MODEL = FaceModel(synthetic_human())
    return _MODEL


_HUMAN_AUS = sorted(load_library("human")["fear"].apex()) + ["AU12L", "AU15R", "AU45", "AU5", "AU51", "AU27"]


@settings(max_examples=60, deadline=None)
@given(st.dictionaries(st.sampled_from(_HUMAN_AUS), st.floats(0.0, 1.0), max_size=8))
def test_any_valid_frame_stays_within_every_limit(aus: dict[str, float]) -> None:
    model = _shared_model()
    sol = model.solve_detailed(aus)
    assert all(0.0 <= c <= 1.0 for c in sol.contractions.values())
    for joint in model.head.joints:
        assert joint.lower_deg <= sol.pose.joint_deg[joint.name] <= joint.upper_deg
    for act in model.anchor_actuators:
        assert act.lower_mm <= sol.pose.actuator_targets[act.role] <= act.upper_mm
    assert np.all(np.isfinite(sol.pose.skin_offset_mm))


@settings(max_examples=40, deadline=None)
@given(
    st.sampled_from(_HUMAN_AUS),
    st.one_of(st.floats(allow_nan=True, allow_infinity=True).filter(lambda x: not 0.0 <= x <= 1.0)),
)
def test_any_out_of_range_value_raises_naming_the_au(name: str, value: float) -> None:
    with pytest.raises(ActionUnitValueError) as info:
        _shared_model().solve({"AU1": 0.2, name: value})
    assert name in str(info.value)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_intensity_scales_the_skin_linearly_below_the_limits(a: float, b: float) -> None:
    model = _shared_model()
    # AU15 alone drives one linear muscle per side: the skin is linear in the intensity
    pa = model.solve({"AU15": a}).skin_offset_mm
    pb = model.solve({"AU15": b}).skin_offset_mm
    unit = model.solve({"AU15": 1.0}).skin_offset_mm
    assert np.allclose(pa, a * unit) and np.allclose(pb, b * unit)


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_twin_meets_any_in_range_anchor_targets_exactly(data: st.DataObject) -> None:
    model = _shared_model()
    targets = {
        act.role: data.draw(st.floats(act.lower_mm, act.upper_mm), label=act.role) for act in model.anchor_actuators
    }
    twin = model.pose_from_targets(targets)
    assert np.all(np.isfinite(twin.skin_offset_mm))
    for act in model.anchor_actuators:
        got = float(np.dot(twin.skin_offset_mm[act.vertex], act.line))
        assert got == pytest.approx(targets[act.role], abs=1e-6)


def test_the_model_exposes_its_au_vocabulary(model: FaceModel) -> None:
    assert {"AU12", "AU12L", "AU12R", "AU26", "AU51"} <= model.au_names
    assert "AU26L" not in model.au_names
    assert model.au_range("au12l") == (0.0, 1.0)
    with pytest.raises(UnknownActionUnitError, match="AU3"):
        model.au_range("AU3")
    with pytest.raises(UnknownActionUnitError, match="AU26L"):
        model.au_range("AU26L")


def test_a_smaller_head_reuses_the_table_unless_strict() -> None:
    head = synthetic_human(8.0)
    keep = tuple(m for m in head.muscles if not m.name.startswith(("risorius", "buccinator")))
    small = SimpleNamespace(**{**vars(head), "muscles": keep})
    with pytest.raises(HeadProfileError, match="(buccinator|risorius)_l.* is not in the head"):
        FaceModel(small, allow_missing=False)
    model = FaceModel(small)  # the default: applied to what the head has
    assert {"risorius_l", "risorius_r", "buccinator_l", "buccinator_r"} == model.mapping.missing
    assert np.allclose(model.solve({"AU20": 1.0}).skin_offset_mm, 0.0)  # validated, moves nothing here
    assert np.abs(model.solve({"AU12": 1.0}).skin_offset_mm).max() > 1.0
