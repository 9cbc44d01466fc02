"""A clipped request rendered as requested vs gated face (real EGL render), written to out/."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def test_render_verdict_of_a_clipped_expression() -> None:
    from servoface.sim.render import egl_missing_reason

    reason = egl_missing_reason()
    if reason:
        pytest.skip(f"headless EGL rendering unavailable: {reason}")
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.face_model import FaceModel
    from servoface.sim.gate import GateConfig, TwinGate
    from servoface.sim.gate.render import render_verdict, verdict_targets
    from servoface.sim.heads import load_head
    from servoface.sim.render.images import save_image

    head = load_head("human")
    fm = FaceModel(head)
    cal = load_calibration(head.calibration_path)
    roles = list(cal.roles)
    fast = GateConfig(max_step_tick={r: 4000 for r in roles}, max_speedup_tick={r: 4000 for r in roles})
    gate = TwinGate(head, cal, 1 / 60, fast, face_model=fm)
    # one mouth corner pulled up (zygomatic servo) and down (depressor servo) hard at once: the coupling
    # rule's case (the shipped expressions no longer trip it; the sadness apex is accepted)
    targets = dict(fm.solve({}).actuator_targets, lip_corner_l=10.0, lip_depressor_l=7.0)
    goals = cal.targets_to_goals(targets)
    verdict = gate.check(goals, gate.neutral_goals())
    assert verdict.kind == "clip" and "coupling" in verdict.checks
    requested, gated = verdict_targets(gate, verdict)
    img = render_verdict(head, requested, gated, verdict, size_px=(320, 320))
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[1] > 640
    left, right = img[:320, :320], img[:320, -320:]
    assert np.abs(left.astype(int) - right.astype(int)).sum() > 0, "gated face should differ from the request"
    out = Path("out") / "gate"
    out.mkdir(parents=True, exist_ok=True)
    save_image(img, out / "verdict_corner_clash.png")
    assert (out / "verdict_corner_clash.png").stat().st_size > 1000
