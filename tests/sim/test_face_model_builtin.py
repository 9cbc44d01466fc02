"""FaceModel on the built-in heads (HEADS' procedural human and dog): tables bind, expressions read,
targets stay in range, the twin reproduces the commanded actuators."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.errors import ActionUnitValueError
from servoface.sim.expressions import load_library
from servoface.sim.face_model import FaceModel, benchmark_solve
from servoface.sim.heads import load_head


@pytest.fixture(scope="module", params=["human", "dog"])
def model(request: pytest.FixtureRequest) -> FaceModel:
    return FaceModel(load_head(request.param))


def _signature(model: FaceModel, aus: dict[str, float]) -> np.ndarray:
    pose = model.solve(aus)
    joints = np.array([pose.joint_deg[j] for j in model.joint_names])
    return np.concatenate([pose.skin_offset_mm.ravel(), joints])


def test_expressions_are_distinct_and_stay_in_range(model: FaceModel) -> None:
    head = model.head
    library = load_library(head.face_type)
    sigs = {}
    for name, expr in library.items():
        pose = model.solve(expr.apex())
        assert set(pose.actuator_targets) == set(head.roles)
        for act in model.joint_actuators:
            assert act.lower_deg <= pose.actuator_targets[act.role] <= act.upper_deg
        for act in model.anchor_actuators:
            assert act.lower_mm <= pose.actuator_targets[act.role] <= act.upper_mm
        for joint in head.joints:
            assert joint.lower_deg <= pose.joint_deg[joint.name] <= joint.upper_deg
        assert np.all(np.isfinite(pose.skin_offset_mm))
        sigs[name] = _signature(model, expr.apex())
    rest = _signature(model, {})
    names = sorted(sigs)
    for i, a in enumerate(names):
        if a != "neutral":
            assert np.abs(sigs[a] - rest).max() > 2.0, a  # mm or deg
        for b in names[i + 1 :]:
            assert np.abs(sigs[a] - sigs[b]).max() > 2.0, (a, b)


def test_twin_reproduces_the_commanded_actuators(model: FaceModel) -> None:
    for expr in load_library(model.head.face_type).values():
        pose = model.solve(expr.apex())
        twin = model.pose_from_targets(pose.actuator_targets)
        for act in model.anchor_actuators:
            got = float(np.dot(twin.skin_offset_mm[act.vertex], act.line))
            assert got == pytest.approx(pose.actuator_targets[act.role], abs=1e-6), (expr.name, act.role)
        for act in model.joint_actuators:
            for joint in act.joints:
                assert twin.joint_deg[joint] == pytest.approx(pose.actuator_targets[act.role])
        assert twin.actuator_targets == pytest.approx(pose.actuator_targets)


def test_human_sides_follow_the_heads_own_left() -> None:
    model = FaceModel(load_head("human"))
    left = model.solve({"AU12L": 0.4}).actuator_targets
    assert left["lip_corner_l"] > 1.0 and left["lip_corner_r"] == pytest.approx(0.0, abs=1e-9)
    wide = model.solve({"AU5": 1.0, "AU45L": 1.0}).joint_deg
    assert wide["upper_lid_l"] == pytest.approx(55.0) and wide["upper_lid_r"] == pytest.approx(-15.0)
    brows = model.solve({"AU1": 0.3}).actuator_targets
    frown = model.solve({"AU4": 0.6}).actuator_targets
    assert brows["brow_inner_l"] > 0.5 and frown["brow_inner_l"] < -0.3
    with pytest.raises(ActionUnitValueError):
        model.solve({"AU12": 1.01})


def test_dog_counter_aus_move_the_other_way() -> None:
    model = FaceModel(load_head("dog"))
    forward = model.solve({"AU5": 0.5}).joint_deg["ear_pan_l"]
    back = model.solve({"AU5": -0.5}).joint_deg["ear_pan_l"]
    assert forward > 5.0 and back < -5.0
    snarl = model.solve({"AU1": 1.0}).actuator_targets["lip_raise_l"]
    relax = model.solve({"AU1": -1.0}).actuator_targets["lip_raise_l"]
    assert snarl > 2.0 and relax < 0.0


def test_benchmark_solve_returns_one_time_per_frame() -> None:
    times = benchmark_solve("human", 20)
    assert len(times) == 20 and all(t > 0.0 for t in times)
