"""Spontaneous blinks: statistics with a seeded RNG, shape, suppression and merging with the face."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.alive import BlinkConfig, BlinkLayer
from servoface.controller.errors import TimelineError
from servoface.controller.timeline import Expression, Movement, Timeline


def test_blink_statistics_with_a_seeded_rng() -> None:
    layer = BlinkLayer("human", seed=42)
    blinks = layer.blinks_until(4000.0)
    starts = np.array([b.start_s for b in blinks])
    intervals = np.diff(starts)
    durations = np.array([b.duration_s for b in blinks])
    assert len(blinks) == pytest.approx(1000, rel=0.1)  # ~15 a minute
    assert intervals.mean() == pytest.approx(4.0, rel=0.06)
    assert intervals.min() >= 0.8  # refractory floor
    assert np.median(intervals) < intervals.mean()  # right-skewed, like human blinking
    assert durations.min() >= 0.15 and durations.max() <= 0.30
    assert durations.mean() == pytest.approx(0.225, abs=0.01)


def test_same_seed_same_blinks_other_seed_other_blinks() -> None:
    a = [(b.start_s, b.duration_s) for b in BlinkLayer("human", seed=1).blinks_until(60)]
    b = [(b.start_s, b.duration_s) for b in BlinkLayer("human", seed=1).blinks_until(60)]
    c = [(b.start_s, b.duration_s) for b in BlinkLayer("human", seed=2).blinks_until(60)]
    assert a == b and a != c


def test_sampling_is_a_pure_function_of_time() -> None:
    forward = BlinkLayer("human", seed=5)
    backward = BlinkLayer("human", seed=5)
    ts = np.linspace(0, 30, 3001)
    f = [forward.closure(float(t)) for t in ts]
    b = [backward.closure(float(t)) for t in ts[::-1]][::-1]
    assert f == b


def test_blink_shape_closes_fully_and_reopens() -> None:
    layer = BlinkLayer("human", seed=3)
    blink = layer.blinks_until(10)[0]
    assert blink.start_s >= 0.5  # no blink right at the start
    close_end = blink.start_s + 0.4 * blink.duration_s
    assert layer.closure(blink.start_s) == 0.0
    assert layer.closure(close_end) == pytest.approx(1.0)
    assert layer.closure(blink.start_s + blink.duration_s) == 0.0
    assert layer.sample(close_end, {}) == {"AU45": pytest.approx(1.0)}
    assert layer.sample(blink.start_s - 0.01, {}) == {}


def test_dog_blinks_with_au15() -> None:
    layer = BlinkLayer("dog", seed=3)
    blink = layer.blinks_until(10)[0]
    assert set(layer.sample(blink.start_s + 0.1 * blink.duration_s, {})) == {"AU15"}


def test_blink_is_suppressed_when_the_face_closes_the_lids() -> None:
    layer = BlinkLayer("human", seed=3)
    blink = layer.blinks_until(10)[0]
    mid = blink.start_s + 0.4 * blink.duration_s
    assert layer.sample(mid, {"AU43": 0.9}) == {}
    assert layer.sample(mid, {"AU45R": 0.85}) == {}
    assert layer.sample(mid, {"AU43": 0.5}) != {}


def test_blink_merges_with_a_half_closed_lid_on_a_timeline() -> None:
    layer = BlinkLayer("human", seed=3)
    blink = layer.blinks_until(10)[0]
    tl = Timeline("human")
    tl.play(Expression("sleepy", 0.1, (Movement({"AU45": 0.5}, 1.0),)).clip(), 0.0)
    tl.add_layer("blink", layer)
    closed = blink.start_s + 0.4 * blink.duration_s
    assert tl.sample_aus(closed)["AU45"] == pytest.approx(1.0)
    assert tl.sample_aus(blink.start_s + blink.duration_s + 0.01)["AU45"] == pytest.approx(0.5)
    assert tl.sample_aus(blink.start_s + 0.05 * blink.duration_s)["AU45"] == pytest.approx(0.5)  # max, not sum


def test_bad_blink_config() -> None:
    with pytest.raises(TimelineError, match="blink.min_duration_s"):
        BlinkConfig(min_duration_s=0.5, max_duration_s=0.3)
    with pytest.raises(TimelineError, match="blink.mean_interval_s"):
        BlinkConfig(mean_interval_s=0.5)
