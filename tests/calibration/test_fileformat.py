"""Calibration files: round trip, atomic save, and errors that name the file, JSON path and expectation."""

from __future__ import annotations

import copy
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from servoface.calibration.errors import CalibrationFileError
from servoface.calibration.fileformat import (
    calibration_from_dict,
    calibration_to_dict,
    load_calibration,
    save_calibration,
)

from tests.calibration.helpers import small_head


def _data() -> dict[str, Any]:
    return calibration_to_dict(small_head())


def test_save_then_load_round_trips_every_servo(tmp_path: Path) -> None:
    cal = small_head()
    path = save_calibration(cal, tmp_path / "sub" / "calibration.json")
    loaded = load_calibration(path)
    assert loaded.roles == cal.roles and loaded.ids == cal.ids
    for a, b in zip(cal.servos, loaded.servos, strict=True):
        assert (a.min_tick, a.max_tick, a.neutral_tick, a.unit, a.model) == (
            b.min_tick,
            b.max_tick,
            b.neutral_tick,
            b.unit,
            b.model,
        )
        t = np.linspace(a.min_target, a.max_target, 50)
        assert np.array_equal(a.to_ticks(t), b.to_ticks(t))
        assert np.array_equal(a.measured_points, b.measured_points)
    assert json.loads(path.read_text())["schema_version"] == 1
    assert [p.name for p in path.parent.iterdir()] == ["calibration.json"]  # no temp file left behind


def test_save_is_atomic_when_writing_fails(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = save_calibration(small_head(), tmp_path / "calibration.json")
    before = path.read_text()

    def broken_fsync(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", broken_fsync)
    with pytest.raises(OSError, match="No space"):
        save_calibration(small_head(), path)
    assert path.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["calibration.json"]


def _mutate(path: str, value: Any) -> dict[str, Any]:
    """Set (or delete, value=KeyError) the item at a dotted path like 'servos.2.curve.points'."""
    data = _data()
    *parents, last = path.split(".")
    node: Any = data
    for key in parents:
        node = node[int(key)] if isinstance(node, list) else node[key]
    key: Any = int(last) if isinstance(node, list) else last
    if value is KeyError:
        del node[key]
    else:
        node[key] = copy.deepcopy(value)
    return data


@pytest.mark.parametrize(
    "where, value, json_path, expected",
    [
        ("schema_version", 2, "schema_version", "unknown schema version 2"),
        ("schema_version", "1", "schema_version", "unknown schema version '1'"),
        ("servos", KeyError, "", "missing key(s) ['servos']"),
        ("servos.1.limits", KeyError, "servos[1]", "missing key(s) ['limits']"),
        ("servos.1.neutral_tick", 2048.5, "servos[1].neutral_tick", "expected an integer"),
        ("servos.1.id", True, "servos[1].id", "expected an integer"),
        ("servos.0.unit", "rad", "servos[0].unit", "expected one of ['deg', 'mm']"),
        ("servos.0.curve.kind", "cubic", "servos[0].curve.kind", "expected one of"),
        ("servos.0.curve.direction", 0, "servos[0].curve.direction", "expected 1 or -1"),
        ("servos.0.curve.offset_tick", float("nan"), "servos[0].curve.offset_tick", "finite"),
        ("servos.2.curve.points.3", [0.5, 1000.0], "servos[2].curve.points", "not strictly monotone"),
        ("servos.2.curve.points.3", [0.0, "x"], "servos[2].curve.points[3][1]", "expected a number"),
        ("servos.2.curve.points.4", [1.0], "servos[2].curve.points[4]", "expected a list of 2 numbers"),
        ("servos.2.curve.points.2", [float("nan"), 2000.0], "servos[2].curve.points[2][0]", "finite"),
        ("servos.3.limits.min_tick", 9000, "servos[3]", "tick limits"),
        ("servos.3.limits.min_target", -50.0, "servos[3]", "do not round into the tick limits"),
        ("servos.1.id", 18, "servos[1].id", "id 18 already used by servos[0] ('jaw')"),
        ("servos.1.role", "jaw", "servos[1].role", "role 'jaw' already used by servos[0]"),
        ("servos.0.nuetral_tick", 2048, "servos[0]", "unexpected key(s) ['nuetral_tick']"),
        ("units.ticks_per_turn", 1024, "units.ticks_per_turn", "expected 4096"),
        ("servos.0.measured_points", "none", "servos[0].measured_points", "expected a list"),
        ("metadata.method", "guess", "metadata.method", "expected one of"),
    ],
)
def test_bad_files_say_what_is_wrong_and_where(
    tmp_path: Path, where: str, value: Any, json_path: str, expected: str
) -> None:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(_mutate(where, value)))  # json.dumps writes NaN as the NaN token
    with pytest.raises(CalibrationFileError) as info:
        load_calibration(path)
    assert info.value.file == str(path)
    assert info.value.json_path == json_path
    assert expected in str(info.value)
    assert str(path) in str(info.value)


def test_unreadable_and_invalid_json_files(tmp_path: Path) -> None:
    with pytest.raises(CalibrationFileError, match="cannot read"):
        load_calibration(tmp_path / "missing.json")
    (tmp_path / "broken.json").write_text('{"schema_version": 1,')
    with pytest.raises(CalibrationFileError, match="not valid JSON at line 1"):
        load_calibration(tmp_path / "broken.json")
    with pytest.raises(CalibrationFileError, match="expected an object"):
        calibration_from_dict([1, 2])


def test_coupling_round_trips(tmp_path: Path) -> None:
    from tests.calibration.test_head import _coupled_head

    cal = _coupled_head()
    loaded = load_calibration(save_calibration(cal, tmp_path / "c.json"))
    goals = {13: 2000, 1: 2300}
    assert loaded.goals_to_targets(goals) == pytest.approx(cal.goals_to_targets(goals))
    data = calibration_to_dict(cal)
    data["servos"][3]["coupling"]["neighbours"] = ["nobody"]
    with pytest.raises(CalibrationFileError, match="unknown role 'nobody'"):
        calibration_from_dict(data)
