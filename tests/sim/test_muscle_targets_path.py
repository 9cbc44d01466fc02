"""The pipeline's targets-only path: `MuscleField.offsets_at` is the full field's offsets at those vertices,
and `FaceModel.actuator_targets` is `solve(aus).actuator_targets`, exactly (not approximately), on random
inputs: the same floats give the same goal ticks."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.au.mapping import AUMapping, check_au
from servoface.sim.errors import SimError
from servoface.sim.face_model import FaceModel
from servoface.sim.heads import load_head
from servoface.sim.muscles.eyelid import EyelidMuscle
from servoface.sim.muscles.field import MuscleField
from servoface.sim.muscles.linear import LinearMuscle
from servoface.sim.muscles.sheet import SheetMuscle
from servoface.sim.muscles.sphincter import SphincterMuscle


def _points(rng: np.random.Generator) -> np.ndarray:
    """A grid face plus points on an eyeball shell (for the lid)."""
    g = np.stack(np.meshgrid(np.linspace(-30, 30, 31), np.linspace(-30, 30, 31)), -1).reshape(-1, 2)
    shell = rng.normal(size=(300, 3))
    shell = shell / np.linalg.norm(shell, axis=1)[:, None] * rng.uniform(11.0, 16.0, size=(300, 1))
    return np.r_[np.c_[g, np.zeros(len(g))], shell + np.array([0.0, 0.0, 5.0])]


def test_offsets_at_is_the_full_offsets_at_those_vertices() -> None:
    rng = np.random.default_rng(2)
    rest = _points(rng)
    field = MuscleField(
        [
            LinearMuscle("a", (-20.0, 0, -2), (0.0, 5, 0), 40, 20, 30, 0.25),
            SheetMuscle("b", (-10.0, 25, -1), (10.0, 25, -1), (-10.0, 10, 0), (10.0, 10, 0), 5.0, 0.25),
            SphincterMuscle("c", (0.0, -10, 0), (15.0, 8.0, 10.0), 0.25),
            EyelidMuscle("lid", (0.0, 0.0, 5.0), 10.0, "upper_lid_l", thickness_mm=1.0, reach_mm=16.0),
        ],
        rest,
    )
    lid_vertices = field.eyelids[0][1].index
    sphincter_vertices = field.sphincters[0][1].index
    assert lid_vertices.size > 10 and sphincter_vertices.size > 10
    for _ in range(200):
        pool = np.r_[rng.integers(0, len(rest), 8), rng.choice(lid_vertices, 4), rng.choice(sphincter_vertices, 4)]
        vertices = rng.choice(pool, size=int(rng.integers(1, 12)))  # repeats included
        c = np.where(rng.random(3) < 0.3, 0.0, rng.uniform(0.0, 1.0, 3))
        lid = {"upper_lid_l": float(rng.choice([0.0, rng.uniform(-20, 50)]))} if rng.random() < 0.8 else None
        assert np.array_equal(field.offsets_at(c, vertices, lid), field.offsets(c, lid)[vertices])
    assert field.offsets_at(np.zeros(3), np.zeros(0, dtype=np.int64)).shape == (0, 3)


def _targets_reference(model: FaceModel, joint_deg: dict[str, float], offsets: np.ndarray) -> dict[str, float]:
    """The targets as `FaceModel` computed them actuator by actuator (before the vectorised clamp)."""
    out = {}
    for act in model.joint_actuators:
        value = float(np.array([joint_deg[j] for j in act.joints]).mean())
        out[act.role] = min(max(value, act.lower_deg), act.upper_deg)
    pulls = np.einsum("ak,ak->a", offsets[model._anchor_vertex], model._anchor_line).tolist()
    for anchor, pull in zip(model.anchor_actuators, pulls, strict=True):
        out[anchor.role] = min(max(pull, anchor.lower_mm), anchor.upper_mm)
    return out


@pytest.mark.parametrize("head_name", ["human", "dog"])
def test_actuator_targets_are_the_solved_ones_exactly(head_name: str) -> None:
    model = FaceModel(load_head(head_name))
    names = sorted(model.au_names)
    rng = np.random.default_rng(5)
    for _ in range(200):
        aus = {}
        for name in rng.choice(names, size=int(rng.integers(0, 8)), replace=False):
            lo, hi = model.au_range(str(name))
            aus[str(name)] = float(rng.uniform(lo, hi)) if rng.random() < 0.9 else float(rng.choice([lo, hi]))
        pose = model.solve(aus)
        fast, slow = model.actuator_targets(aus), dict(pose.actuator_targets)
        assert fast == slow and list(fast) == list(slow)
        assert slow == _targets_reference(model, pose.joint_deg, pose.skin_offset_mm)
    for bad in ({"AU12": float("nan")}, {"AU12": 7.0}, {"NOPE": 0.1}):
        with pytest.raises(SimError):
            model.actuator_targets(bad)


def _channel_values_reference(mapping: AUMapping, aus: dict[object, object]) -> np.ndarray:
    """`AUMapping.channel_values` as it was: every name parsed and checked by `check_au`."""
    values = np.zeros(len(mapping.channels))
    for name, value in aus.items():
        number, side, x = check_au(mapping.table, name, value)
        for s in ("L", "R") if mapping.table.entries[number].sided and not side else (side,):
            values[mapping.channel_index[(number, s)]] += x
    return np.clip(values, mapping.low, mapping.high)


def _outcome(f: object, aus: dict[object, object]) -> tuple[str, object]:
    try:
        return "ok", f(aus).tolist()  # type: ignore[operator]
    except SimError as err:
        return type(err).__name__, str(err)


def test_channel_values_with_known_names_kept_is_the_checked_path() -> None:
    mapping = FaceModel(load_head("human")).mapping
    names: list[object] = sorted(mapping.table.names()) + ["au12l", "AU012", "AU12X", "AU999", "", 12]
    odd: list[object] = [float("nan"), float("inf"), -0.5, 1.5, 7.0, True, 1, np.float64(0.4), "0.3", None]
    rng = np.random.default_rng(6)
    differ = 0
    for _ in range(600):
        aus: dict[object, object] = {}
        for _ in range(int(rng.integers(0, 6))):
            name = names[int(rng.integers(len(names)))]
            aus[name] = odd[int(rng.integers(len(odd)))] if rng.random() < 0.15 else float(rng.uniform(-1.2, 1.2))
        got = _outcome(mapping.channel_values, aus)
        want = _outcome(lambda a: _channel_values_reference(mapping, a), aus)
        assert got == want, aus
        differ += got[0] != "ok"
    assert 100 < differ < 500  # both accepted and refused frames


def _walk(model: FaceModel, rng: np.random.Generator, steps: int) -> list[dict[str, float]]:
    """AU frames in which one AU changes at a time, often one that only turns joints (gaze, head)."""
    names = sorted(model.au_names)
    joint_only = [n for n in names if not model.mapping.evaluate(_one(model, n))[0].any()]
    assert joint_only
    aus: dict[str, float] = {}
    frames = []
    for _ in range(steps):
        name = str(rng.choice(joint_only if rng.random() < 0.6 else names))
        lo, hi = model.au_range(name)
        aus = {**aus, name: float(rng.uniform(lo, hi))}
        if rng.random() < 0.05:
            aus = {}
        frames.append(aus)
    return frames


def _one(model: FaceModel, name: str) -> dict[str, float]:
    lo, hi = model.au_range(name)
    return {name: hi if hi > 0 else lo}


@pytest.mark.parametrize("head_name", ["human", "dog"])
def test_kept_anchor_pulls_give_the_solved_targets_along_a_walk(head_name: str) -> None:
    model = FaceModel(load_head(head_name))
    rng = np.random.default_rng(6)
    kept = 0
    for aus in _walk(model, rng, 400):
        before = model._anchors_kept
        fast = model.actuator_targets(aus)
        kept += model._anchors_kept is before and before is not None
        slow = dict(model.solve(aus).actuator_targets)
        assert list(fast.items()) == list(slow.items())
    assert kept > 100  # the kept pulls were used (frames that moved joints only)


class _LidField:
    """A head's field as if it had eyelids: its anchor offsets then depend on the joints too."""

    def __init__(self, field: MuscleField) -> None:
        self.field = field
        self.eyelids = [("lid",)]

    def offsets_at(self, c: np.ndarray, vertices: np.ndarray, joint_deg: dict[str, float] | None) -> np.ndarray:
        assert joint_deg is not None
        return self.field.offsets_at(c, vertices) + 0.01 * sum(joint_deg.values())


def test_kept_anchor_pulls_with_eyelids_are_kept_per_joints_too() -> None:
    model = FaceModel(load_head("human"))
    model.field = _LidField(model.field)  # type: ignore[assignment]
    rng = np.random.default_rng(7)
    for aus in _walk(model, rng, 300):
        fast = model.actuator_targets(aus)
        model._anchors_kept = None  # the straightforward path: nothing kept
        assert list(fast.items()) == list(model.actuator_targets(aus).items())


def _bits(x: np.ndarray) -> bytes:
    return np.asarray(x, dtype=np.float64).tobytes()


@pytest.mark.parametrize("head_name", ["human", "dog"])
def test_split_and_joint_values_are_the_plain_numpy_bit_for_bit(head_name: str) -> None:
    """`AUMapping.split` (one maximum over both halves) and `FaceModel._joint_values` (`mean`'s sum and
    division without its wrappers) against the plain numpy forms, bit for bit (signed zeros included)."""
    model = FaceModel(load_head(head_name))
    mapping = model.mapping
    names = sorted(model.au_names)
    rng = np.random.default_rng(8)
    for _ in range(300):
        aus: dict[str, float] = {}
        for name in rng.choice(names, size=int(rng.integers(0, 8)), replace=False):
            lo, hi = model.au_range(str(name))
            aus[str(name)] = float(rng.choice([rng.uniform(lo, hi), lo, hi, 0.0, -0.0 if lo < 0 else 0.0]))
        x = mapping.channel_values(aus)
        want = np.concatenate([np.maximum(x, 0.0), np.maximum(-x, 0.0)])
        assert _bits(mapping.split(aus)) == _bits(want)
        joint = rng.uniform(-90.0, 90.0, len(model.joint_names)) * (rng.random(len(model.joint_names)) < 0.7)
        if rng.random() < 0.2:
            joint = -joint  # (zeros of both signs)
        first, multi, j_lo, j_hi = model._target_plan[:4]
        means = joint[first]
        for k, cols, _n in multi:
            means[k] = joint[cols].mean()
        assert multi and _bits(model._joint_values(joint)) == _bits(np.minimum(np.maximum(means, j_lo), j_hi))
