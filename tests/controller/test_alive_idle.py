"""Idle motion: small, smooth, seeded, and fading out while something plays."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.alive import IdleConfig, IdleLayer
from servoface.controller.errors import TimelineError
from servoface.controller.timeline import Expression, Movement, Timeline


def test_idle_is_small_smooth_and_deterministic() -> None:
    a = IdleLayer("human", seed=4)
    b = IdleLayer("human", seed=4)
    ts = np.arange(0.0, 30.0, 0.02)
    yaw = np.array([a.channel("head_yaw", float(t)) for t in ts])
    assert np.abs(yaw).max() <= 1.0 and np.abs(yaw).max() > 0.1
    assert [b.channel("head_yaw", float(t)) for t in ts[::-1]][::-1] == list(yaw)
    step = np.abs(np.diff(yaw)).max()  # C2 spline at 2.5 s knots: tiny per-frame steps
    assert step < 0.05
    frames = [a.sample(float(t)) for t in ts]
    for f in frames:
        assert all(0 <= v <= 0.04 + 1e-12 for v in f.values())
    assert any(f.get("AU51", 0) > 0 for f in frames) and any(f.get("AU52", 0) > 0 for f in frames)
    assert IdleLayer("human", seed=5).channel("head_yaw", 3.0) != a.channel("head_yaw", 3.0)


def test_idle_fades_while_a_clip_plays() -> None:
    tl = Timeline("human")
    tl.play(Expression("smile", 2.0, (Movement({"AU12": 0.5}, 1.0),)).clip(), 5.0)
    idle = IdleLayer("human", seed=1, busy=tl.is_playing)
    tl.add_layer("idle", idle)
    assert idle.gain(1.0) == 1.0
    assert idle.gain(6.5) == 0.0 and idle.sample(6.5) == {}
    assert 0.0 < idle.gain(7.5) < 1.0  # fading back in
    assert idle.gain(9.0) == 1.0
    dog = IdleLayer("dog", seed=1).sample(1.0)
    assert set(dog) == {"AU9", "AU10", "AU11", "AU12", "AU13"}


def test_bad_idle_config() -> None:
    with pytest.raises(TimelineError, match="idle.head_amplitude"):
        IdleConfig(head_amplitude=0.9)
