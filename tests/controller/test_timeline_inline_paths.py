"""The timeline sample's per-frame helpers written without helper calls or generators (easings with the
clamp inline, a channel's key values inline, the blink's lid test and the idle gain as loops) against
their previous forms, kept here, on random inputs: the same floats, bit for bit."""

from __future__ import annotations

import bisect
import math
import struct
from collections.abc import Mapping

import numpy as np
import pytest
from servoface.controller.alive.blink import LID_AUS, BlinkConfig, BlinkLayer
from servoface.controller.alive.idle import IdleConfig, IdleLayer
from servoface.controller.timeline.clip import ChannelClip, Key
from servoface.controller.timeline.easing import EASINGS, linear, min_jerk


def _bits(x: float) -> bytes:
    return struct.pack("<d", x)


def _clamp01(u: float) -> float:
    return 0.0 if u <= 0.0 else 1.0 if u >= 1.0 else u


def _linear_reference(u: float) -> float:
    return _clamp01(u)


def _min_jerk_reference(u: float) -> float:
    u = _clamp01(u)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


def _odd_floats(rng: np.random.Generator, n: int) -> list[float]:
    special = [0.0, -0.0, 1.0, math.nextafter(1.0, 2.0), math.nextafter(0.0, -1.0), 5e-324, math.nan, math.inf,
               -math.inf, 0.5]  # fmt: skip
    return [float(rng.choice(special)) if rng.random() < 0.2 else float(rng.uniform(-0.5, 1.5)) for _ in range(n)]


def test_easings_with_the_clamp_inline_are_the_clamped_forms() -> None:
    rng = np.random.default_rng(51)
    for u in _odd_floats(rng, 4000):
        assert _bits(linear(u)) == _bits(_linear_reference(u))
        assert _bits(min_jerk(u)) == _bits(_min_jerk_reference(u))


def _channel_reference(clip: ChannelClip, au: str, t_s: float, start: float) -> float:
    """`ChannelClip._channel` as it was (each key's value through a helper)."""

    def value(key: Key) -> float:
        return start if key.value is None else key.value

    keys = clip.channels[au]
    times = [k.t_s for k in keys]
    i = bisect.bisect_right(times, t_s)
    if i == 0:
        return value(keys[0])
    if i == len(keys):
        return value(keys[-1])
    a, b = keys[i - 1], keys[i]
    span = b.t_s - a.t_s
    va, vb = value(a), value(b)
    return va + (vb - va) * b.easing((t_s - a.t_s) / span)


def test_a_channel_with_its_key_values_inline_is_the_plain_channel() -> None:
    rng = np.random.default_rng(52)
    easings = list(EASINGS.values())
    for _ in range(300):
        channels = {}
        for au in ("AU1", "AU12", "AU26")[: int(rng.integers(1, 4))]:
            times = np.sort(rng.choice([0.0, 0.5, 1.0, *rng.uniform(0, 2, 4)], size=int(rng.integers(1, 6))))
            channels[au] = tuple(
                Key(
                    float(t),
                    None if rng.random() < 0.3 else float(rng.uniform(0, 1)),
                    easings[int(rng.integers(len(easings)))],
                )
                for t in times
            )
        clip = ChannelClip(channels, 2.0)
        for t in [*rng.uniform(-0.2, 2.2, 10), *(k.t_s for keys in channels.values() for k in keys)]:
            start = float(rng.uniform(0, 1))
            for au in channels:
                got = clip._channel(au, channels[au], float(t), start)
                assert _bits(got) == _bits(_channel_reference(clip, au, float(t), start))


def _suppressed_reference(layer: BlinkLayer, below: Mapping[str, float]) -> bool:
    return any(below.get(au, 0.0) >= layer.config.suppress_at for au in LID_AUS[layer.face_type])


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_the_blink_lid_test_as_a_loop_is_the_any_form(face_type: str) -> None:
    rng = np.random.default_rng(53)
    lids = list(LID_AUS[face_type])
    for _ in range(2000):
        layer = BlinkLayer(face_type, config=BlinkConfig(suppress_at=float(rng.choice([0.8, 0.5, 1.0]))))  # type: ignore[arg-type]
        below = {str(au): float(rng.choice([0.0, 0.5, 0.8, 1.0, rng.uniform(-1, 1), math.nan]))
                 for au in rng.choice([*lids, "AU12", "AU1"], size=int(rng.integers(0, 5)))}  # fmt: skip
        assert layer.suppressed(below) == _suppressed_reference(layer, below)


def _gain_reference(layer: IdleLayer, t_s: float) -> float:
    if layer.busy is None:
        return 1.0
    n = 8
    quiet = sum(not layer.busy(t_s - layer.config.fade_s * j / (n - 1)) for j in range(n))
    return quiet / n


def test_the_idle_gain_as_a_loop_is_the_sum_form() -> None:
    rng = np.random.default_rng(54)
    for _ in range(300):
        spans = np.sort(rng.uniform(0, 10, 2 * int(rng.integers(0, 4))))
        asked: list[float] = []  # the times asked, in order (the same arithmetic gives the same times)

        def busy(t: float, s: np.ndarray = spans, asked: list[float] = asked) -> bool:
            asked.append(t)
            return bool(int(np.searchsorted(s, t, side="right")) % 2)

        layer = IdleLayer("human", config=IdleConfig(fade_s=float(rng.uniform(0.1, 2.0))), busy=busy)
        for t in [*rng.uniform(-1, 11, 20), *spans]:
            got = layer.gain(float(t))
            got_asked = [_bits(x) for x in asked]
            asked.clear()
            assert _bits(got) == _bits(_gain_reference(layer, float(t)))
            assert got_asked == [_bits(x) for x in asked]
            asked.clear()
    assert IdleLayer("human").gain(3.0) == 1.0
