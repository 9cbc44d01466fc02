"""A calibration put into service without a restart (controller/studio/live_calibration.py): the goals on
the emulator's wire follow the new calibration, its limits are written to the servos, nothing outside
them is sent."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from servoface.calibration import load_calibration
from servoface.controller.head_servos import servo_specs

from tests.studio.conftest import StudioRig

SOFTER = 0.8  # the new jaw calibration: 80 % of the ticks per degree


def _settled_goals(rig: StudioRig) -> dict[int, int]:
    """The wire goals once unchanged over 10 frames (speed caps ease a change over a few frames)."""
    seen: list[tuple[int, dict[int, int]]] = []

    def settled() -> bool:
        index, goals = rig.service.last_trace.index, rig.goals()  # type: ignore[union-attr]
        seen.append((index, goals))
        earlier = [g for i, g in seen if i <= index - 10]
        return bool(earlier) and earlier[-1] == goals

    rig.wait_for(settled, what="the wire goals settled")
    return seen[-1][1]


def _softer_jaw_file(rig: StudioRig, out: Path) -> dict[str, Any]:
    path = rig.service.head.calibration_path
    assert path is not None
    data = json.loads(Path(path).read_text())
    jaw = next(s for s in data["servos"] if s["role"] == "jaw")
    assert jaw["curve"]["kind"] == "linear"
    scale = jaw["curve"]["scale_tick_per_unit"] * SOFTER
    offset = jaw["curve"]["offset_tick"]
    jaw["curve"]["scale_tick_per_unit"] = scale
    lim = jaw["limits"]
    lo_t, hi_t = lim["min_target"], lim["max_target"]
    lim["min_tick"], lim["max_tick"] = round(offset + scale * lo_t), round(offset + scale * hi_t)
    jaw["measured_points"] = [[t, offset + scale * t] for t, _ in jaw["measured_points"]]
    out.write_text(json.dumps(data, indent=1))
    return jaw


def test_an_applied_calibration_drives_the_wire_at_once(studio: StudioRig, tmp_path: Path) -> None:
    rig = studio
    jaw_id = next(a.servo.id for a in rig.service.head.actuators if a.role == "jaw")
    aus = {"AU26": 0.8}
    assert rig.client.post("/api/aus", json={"aus": aus, "transition_s": 0.1}).status_code == 202
    rig.wait_for(lambda: rig.service.status().tracks["studio"].state == "holding", what="the pose")
    before = _settled_goals(rig)
    old = rig.service.pipeline.calibration
    target = rig.service.pipeline.targets_for(aus)["jaw"]
    rest = {r: old[r].neutral_target for r in old.roles}
    assert before[jaw_id] == old.targets_to_goals({**rest, "jaw": target})[jaw_id]

    jaw = _softer_jaw_file(rig, tmp_path / "softer.json")
    new = load_calibration(tmp_path / "softer.json")
    writes_before = len(rig.chain.goal_writes())
    r = rig.client.post("/api/calibration/apply", json={"file": "softer.json"})
    assert r.status_code == 200, r.text
    assert rig.service.pipeline.calibration["jaw"].max_tick == jaw["limits"]["max_tick"]
    # the same AUs, still held: the jaw's goal on the wire is now the new calibration's for the same target
    expected = new.targets_to_goals({**{r_: new[r_].neutral_target for r_ in new.roles}, "jaw": target})[jaw_id]
    rig.wait_for(lambda: rig.goal_tick(jaw_id) == expected, what="the jaw's goal per the new calibration")
    after = _settled_goals(rig)
    assert after[jaw_id] == expected != before[jaw_id]
    assert abs((after[jaw_id] - 2048) - SOFTER * (before[jaw_id] - 2048)) <= 2
    assert {s: g for s, g in after.items() if s != jaw_id} == {s: g for s, g in before.items() if s != jaw_id}
    # the new limits are the servo's own backstop, and nothing outside them went on the wire
    spec = next(s for s in servo_specs(rig.service.head, rig.service.pipeline.calibration) if s.servo_id == jaw_id)
    assert rig.chain.servo(jaw_id).read_register("Max Position Limit") == spec.max_position_tick
    lo, hi = rig.service.pipeline.calibration.position_limits_tick()[jaw_id]
    assert all(lo <= t <= hi for _, sid, t in rig.chain.goal_writes()[writes_before:] if sid == jaw_id)
    assert all(rig.torque(s) == 1 for s in rig.chain.ids)  # torque as it was
    assert rig.client.get("/api/head").json()["servos"][0]  # the head info is re-read
    head_jaw = next(s for s in rig.client.get("/api/head").json()["servos"] if s["role"] == "jaw")
    assert head_jaw["max_tick"] == jaw["limits"]["max_tick"]


def test_a_bad_calibration_file_is_refused_and_changes_nothing(studio: StudioRig, tmp_path: Path) -> None:
    rig = studio
    running = rig.service.pipeline.calibration
    (tmp_path / "broken.json").write_text("{not json")
    for body, field in (
        ({"file": "../x.json"}, "file"),
        ({"file": "missing.json"}, "file"),
        ({"file": "broken.json"}, "file"),
        ({"file": 3}, "file"),
        ({"file": "a.json", "more": 1}, "more"),
    ):
        r = rig.client.post("/api/calibration/apply", json=body)
        assert 400 <= r.status_code < 500 and r.json()["error"]["field"] == field, r.text
    assert rig.service.pipeline.calibration is running


def test_a_calibration_for_other_servos_is_refused_by_the_driver_and_the_pipeline(studio: StudioRig) -> None:
    import dataclasses

    import pytest
    from servoface.calibration import HeadCalibration
    from servoface.hardware.errors import HardwareConfigError
    from servoface.sim.errors import SimError

    rig = studio
    running = rig.service.pipeline.calibration
    specs = servo_specs(rig.service.head, running)

    def job(driver: Any) -> list[str]:
        refused = []
        for bad in (
            specs[1:],
            [
                dataclasses.replace(specs[0], model="XM430-W350" if specs[0].model != "XM430-W350" else "XL430-W250"),
                *specs[1:],
            ],
        ):
            try:
                driver.respec(bad)
            except HardwareConfigError as err:
                refused.append(str(err))
        return refused

    refused = rig.server.studio.lender.run(job)
    assert len(refused) == 2 and "ids" in refused[0] and "servo" in refused[1]
    fewer = HeadCalibration(running.head, [running[r] for r in running.roles[1:]])
    with pytest.raises(SimError, match="lacks servo role"):
        rig.service.pipeline.use_calibration(fewer, rig.service.pipeline.gate)
    assert rig.service.pipeline.calibration is running
