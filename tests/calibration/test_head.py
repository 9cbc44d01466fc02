"""HeadCalibration: role <-> id translation, batch forms, duplicates, coupled anchors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from servoface.calibration.errors import (
    CalibrationError,
    NotMonotoneError,
    TargetOutOfRangeError,
    UnknownServoError,
)
from servoface.calibration.fitting import fit_coupling
from servoface.calibration.head import HeadCalibration

from tests.calibration.helpers import small_head


def test_targets_to_goals_translates_roles_to_ids() -> None:
    cal = small_head()
    goals = cal.targets_to_goals({"jaw": 10.0, "upper_lid_r": 10.0, "brow_inner_l": 0.0})
    assert set(goals) == {18, 6, 1}
    assert goals[18] == 2048 + round(10 * 4096 / 360)
    assert goals[6] == 2048 - round(10 * 4096 / 360)  # mirrored servo
    assert goals[1] == 2048
    back = cal.goals_to_targets(goals)
    assert back["jaw"] == pytest.approx(10.0, abs=360 / 4096)
    assert cal.neutral_goals() == {18: 2048, 6: 2048, 1: 2048, 13: 2048}
    assert cal.neutral_targets() == pytest.approx({"jaw": 0, "upper_lid_r": 0, "brow_inner_l": 0, "lip_corner_r": 0})


def test_mapping_forms_are_all_or_nothing_and_name_the_problem() -> None:
    cal = small_head()
    with pytest.raises(UnknownServoError, match="no servo with role 'nose'"):
        cal.targets_to_goals({"jaw": 1.0, "nose": 1.0})
    with pytest.raises(TargetOutOfRangeError, match="'jaw'"):
        cal.targets_to_goals({"brow_inner_l": 1.0, "jaw": 26.0})
    with pytest.raises(UnknownServoError, match="no servo with id 99"):
        cal.goals_to_targets({99: 2048})


def test_batch_forms_match_the_mapping_forms() -> None:
    cal = small_head()
    rng = np.random.default_rng(3)
    lo = np.array([cal[r].min_target for r in cal.roles])
    hi = np.array([cal[r].max_target for r in cal.roles])
    targets = lo + rng.uniform(0, 1, (500, len(cal))) * (hi - lo)
    goals = cal.targets_to_goals_array(targets)
    assert goals.shape == (500, 4) and goals.dtype == np.int64
    row = dict(zip(cal.roles, targets[7], strict=True))
    assert cal.targets_to_goals(row) == dict(zip(cal.ids, goals[7].tolist(), strict=True))
    back = cal.goals_to_targets_array(goals)
    res = np.array([cal[r].target_resolution() for r in cal.roles])
    assert np.all(np.abs(back - targets) <= res + 1e-9)
    with pytest.raises(CalibrationError, match=r"shape \(n, 4\)"):
        cal.targets_to_goals_array(targets[:, :3])
    targets[3, 2] = np.nan
    with pytest.raises(TargetOutOfRangeError, match="'brow_inner_l'"):
        cal.targets_to_goals_array(targets)


def test_duplicate_roles_and_ids_are_refused() -> None:
    servos = list(small_head().servos)
    with pytest.raises(CalibrationError, match="servo id 18 is used by both 'jaw' and 'jaw2'"):
        HeadCalibration("x", servos + [dataclasses.replace(servos[0], role="jaw2")])
    with pytest.raises(CalibrationError, match="role 'jaw' appears twice"):
        HeadCalibration("x", servos + [dataclasses.replace(servos[0], servo_id=40)])
    with pytest.raises(CalibrationError, match="at least one servo"):
        HeadCalibration("x", [])


def _coupled_head() -> HeadCalibration:
    """lip_corner_r's pull also depends on brow_inner_l's tick (an artificial but clear neighbour)."""
    cal = small_head()
    corner, brow = cal["lip_corner_r"], cal["brow_inner_l"]
    own = np.linspace(corner.min_tick, corner.max_tick, 6)
    nb = np.linspace(brow.min_tick, brow.max_tick, 4)
    grid = np.stack(np.meshgrid(own, nb, indexing="ij"), axis=-1).reshape(-1, 2)
    pull = corner.to_targets(grid[:, 0]) - 0.002 * (grid[:, 1] - 2048)
    coupling = fit_coupling(corner, ["brow_inner_l"], grid, pull)
    servos = [dataclasses.replace(s, coupling=coupling) if s.role == "lip_corner_r" else s for s in cal.servos]
    return HeadCalibration("coupled", servos)


def test_coupled_anchor_is_solved_after_its_neighbour() -> None:
    cal = _coupled_head()
    for brow_mm in (-3.0, 0.0, 6.0):
        goals = cal.targets_to_goals({"lip_corner_r": 4.0, "brow_inner_l": brow_mm})
        back = cal.goals_to_targets(goals)
        assert back["lip_corner_r"] == pytest.approx(4.0, abs=0.02)
        assert back["brow_inner_l"] == pytest.approx(brow_mm, abs=0.02)
    a = cal.targets_to_goals({"lip_corner_r": 4.0, "brow_inner_l": -3.0})[13]
    b = cal.targets_to_goals({"lip_corner_r": 4.0, "brow_inner_l": 6.0})[13]
    assert a != b  # the neighbour's position changes the servo tick for the same pull
    targets = np.array([[5.0, 0.0, b_mm, 4.0] for b_mm in (-3.0, 6.0)])
    goals = cal.targets_to_goals_array(targets)
    assert goals[:, 3].tolist() == [a, b]
    assert np.allclose(cal.goals_to_targets_array(goals)[:, 3], 4.0, atol=0.02)
    with pytest.raises(TargetOutOfRangeError, match="'lip_corner_r'"):
        cal.targets_to_goals({"lip_corner_r": 50.0})


def test_coupling_must_be_monotone_in_the_own_tick_and_acyclic() -> None:
    cal = small_head()
    corner = cal["lip_corner_r"]
    own = np.linspace(corner.min_tick, corner.max_tick, 6)
    grid = np.stack(np.meshgrid(own, [1800.0, 2000.0, 2300.0], indexing="ij"), axis=-1).reshape(-1, 2)
    valley = ((grid[:, 0] - 1800) / 200.0) ** 2 + 0.001 * grid[:, 1]
    with pytest.raises(NotMonotoneError, match="not strictly monotone in its own tick"):
        fit_coupling(corner, ["brow_inner_l"], grid, valley)
    good = _coupled_head()
    brow = good["brow_inner_l"]
    back_coupling = dataclasses.replace(good["lip_corner_r"].coupling, neighbours=("lip_corner_r",))  # type: ignore[type-var]
    servos = [s for s in good.servos if s.role != "brow_inner_l"] + [dataclasses.replace(brow, coupling=back_coupling)]
    with pytest.raises(CalibrationError, match="coupling cycle"):
        HeadCalibration("cyclic", servos)
