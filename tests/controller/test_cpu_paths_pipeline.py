"""The 50 Hz frame's cheap paths end to end: the shipped performances played through an offline pipeline
(muscle model, calibration, twin gate) give the same AUs, targets, goals and verdicts frame by frame as with
every one of those paths replaced by its straightforward form (the timeline's plain blend, track scan and
gaze; nothing kept between frames in the muscle model; the calibration's batch path)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from servoface.calibration import HeadCalibration
from servoface.controller.face import Face
from servoface.controller.script import SCRIPTS_DIR, load_script
from servoface.sim.face_model import FaceModel

from tests.controller.test_timeline_sample_paths import _plain


def _frames(face: Face, script_name: str, plain: bool, n: int) -> list[tuple[Any, ...]]:
    script = load_script(SCRIPTS_DIR / script_name)
    pipeline = face.pipeline
    if plain:
        script = _plain(script)
        model: FaceModel = pipeline.face
        fast_targets = model.actuator_targets

        def targets_nothing_kept(aus: Any) -> dict[str, float]:
            model._anchors_kept = None
            return fast_targets(aus)

        pipeline.face.actuator_targets = targets_nothing_kept  # type: ignore[method-assign]
        cal: HeadCalibration = pipeline.calibration
        cal.column_goals = cal.column_goals_plain  # type: ignore[method-assign]
    out = []
    for k in range(n):
        frame = script.sample(k / 50)
        trace = pipeline.step(frame, k / 50)
        out.append((dict(frame.aus), trace.targets, trace.goals_requested, trace.verdict, trace.goals_sent))
    return out


@pytest.mark.parametrize(
    ("head_name", "script_name"), [("human", "human_performance.toml"), ("dog", "dog_performance.toml")]
)
def test_performance_frames_equal_the_straightforward_paths(head_name: str, script_name: str) -> None:
    n = int(load_script(SCRIPTS_DIR / script_name).end_s * 50) + 1  # the whole performance
    fast = _frames(Face.offline(head_name), script_name, False, n)
    plain = _frames(Face.offline(head_name), script_name, True, n)
    for k, (a, b) in enumerate(zip(fast, plain, strict=True)):
        assert repr(a[:2]) == repr(b[:2]), k  # AUs and targets, bit for bit
        assert a[2:] == b[2:], k  # goals, verdict, what the gate let through
    assert np.mean([f[0] != {} for f in fast]) > 0.5  # the face moved in most frames
