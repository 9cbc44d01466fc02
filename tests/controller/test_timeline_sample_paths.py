"""The timeline sample's cheap paths against the straightforward ones, on random inputs: `Timeline.is_playing`
from merged playing spans vs a scan of every track (boundary times included, tracks changed between
queries); `BlendPolicy.blend` (kept priority order, ``only=``) vs `blend_plain`; a gaze shift's settled
pose kept vs recomputed; and whole scripts sampled with every fast path vs with the plain ones."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np
import pytest
from servoface.controller.alive.blink import BlinkConfig, BlinkLayer
from servoface.controller.alive.gaze import GazeConfig
from servoface.controller.alive.gaze_layer import GazeLayer, _split, angles_to_aus
from servoface.controller.alive.idle import CHANNELS, IdleLayer, _bspline
from servoface.controller.script import SCRIPTS_DIR, Script, load_script
from servoface.controller.timeline import Timeline
from servoface.controller.timeline.blend import DEFAULT_PRIORITY, HUMAN_DIRECTION_PAIRS, BlendPolicy
from servoface.controller.timeline.envelope import Envelope, EnvelopeClip


def _times_around(values: list[float]) -> list[float]:
    out = []
    for v in values:
        out += [v, math.nextafter(v, -math.inf), math.nextafter(v, math.inf)]
    return out


def test_is_playing_equals_the_scan_of_every_track_at_boundaries_and_after_changes() -> None:
    rng = np.random.default_rng(41)
    for _ in range(30):
        timeline = Timeline("human")
        edges: list[float] = []
        for k in range(int(rng.integers(1, 12))):
            track = str(rng.choice(["face", "gesture", "speech", "head"]))
            at = float(rng.choice([0.0, 1.0, 2.5])) if rng.random() < 0.3 else float(rng.uniform(0, 10))
            d = 0.0 if rng.random() < 0.1 else float(rng.uniform(0.01, 3.0))
            clip = EnvelopeClip({"AU12": 0.5}, Envelope(d, d / 2, d / 3))
            placed = timeline.play(clip, at, track=track)
            edges += [placed.start_s, placed.end_s]
            if rng.random() < 0.1:
                timeline.track(track).clear()
            times = _times_around(edges) + [float(t) for t in rng.uniform(-1, 15, size=40)]
            for t in times:
                assert timeline.is_playing(t) == timeline.is_playing_plain(t), (k, t)


def _only_view(full: Mapping[str, float], only: frozenset[str], policy: BlendPolicy) -> dict[str, float]:
    wanted = set(only) | {a for pair in policy.antagonists if set(pair) & only for a in pair}
    return {au: v for au, v in full.items() if au in wanted}


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_blend_equals_blend_plain_and_only_gives_those_aus_of_it(face_type: str) -> None:
    policy = BlendPolicy.for_face(face_type, rules={"AU12": "override"} if face_type == "human" else None)  # type: ignore[arg-type]
    pairs = [a for pair in HUMAN_DIRECTION_PAIRS for a in pair] if face_type == "human" else []
    aus = [f"AU{n}" for n in (1, 2, 4, 5, 6, 12, 25, 26, 43, 45, 51, 61)] + ["AU12L", "AU45L"] + pairs
    tracks = [*DEFAULT_PRIORITY, "custom"]
    rng = np.random.default_rng(42)
    for _ in range(1500):
        contributions = []
        for _ in range(int(rng.integers(1, 6))):
            names = rng.choice(aus, size=int(rng.integers(0, 9)), replace=False)
            odd = [-0.0, 0.0, 1.0, -1.0]
            values = {
                str(a): odd[int(rng.integers(4))] if rng.random() < 0.1 else float(rng.uniform(-1.3, 1.3))
                for a in names
            }
            contributions.append((str(rng.choice(tracks)), values))
        lo, hi = (-1.0, 1.0) if rng.random() < 0.7 else (0.0, 1.0)
        want = policy.blend_plain(contributions, lo, hi)
        got = policy.blend(contributions, lo, hi)
        assert repr(list(got.items())) == repr(list(want.items()))  # (repr: the sign of a zero too)
        only = frozenset(str(a) for a in rng.choice(aus, size=int(rng.integers(0, 5)), replace=False))
        part = policy.blend(contributions, lo, hi, only)
        assert part == _only_view(want, only, policy)


def _gaze_plain(layer: GazeLayer, t_s: float) -> dict[str, float]:
    i = int(np.searchsorted(np.array(layer._starts), t_s, side="right")) - 1
    if i < 0:
        return {}
    p = layer._pose(i, t_s)
    cfg = layer.config
    return angles_to_aus(layer.face_type, cfg, p.head_yaw_deg, p.head_pitch_deg, p.eye_yaw_deg, p.eye_pitch_deg)


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_gaze_settled_pose_kept_equals_the_pose_recomputed(face_type: str) -> None:
    rng = np.random.default_rng(43)
    layer = GazeLayer(face_type)  # type: ignore[arg-type]
    cfg = layer.config
    for k in range(12):
        at = float(rng.uniform(0, 12))
        target = None if rng.random() < 0.2 else (float(rng.uniform(-600, 600)), float(rng.uniform(-300, 500)), 900.0)
        layer.look_at(at, target)  # a shift scheduled between queries: the kept poses must not outlive it
        ends = [s.at_s + cfg.head_move_s for s in layer.shifts] + [s.at_s + cfg.saccade_s for s in layer.shifts]
        for t in _times_around(ends) + [float(t) for t in rng.uniform(-1, 14, size=60)]:
            got = layer.sample(t)
            assert list(got.items()) == list(_gaze_plain(layer, t).items()), (k, t)
            got["AU61"] = 99.0  # a caller changing its copy changes nothing kept
        if k == 6:
            layer.config = dataclasses.replace(cfg, head_move_s=cfg.head_move_s * 2)  # kept per config
            cfg = layer.config


def _plain(script: Script) -> Script:
    """``script`` with its timeline sampled the straightforward way: every blend in full by `blend_plain`,
    `is_playing` by scanning the tracks, the gaze recomputed every frame."""
    timeline = script.timeline
    policy = timeline.blend

    class PlainPolicy:
        def blend(self, contributions, lo=-1.0, hi=1.0, only=None):  # type: ignore[no-untyped-def]
            return policy.blend_plain(contributions, lo, hi)  # the whole pose, whatever a layer reads

    timeline.blend = PlainPolicy()  # type: ignore[assignment]
    for name in timeline.layer_names:
        layer = timeline.layer(name)
        if isinstance(layer, IdleLayer) and layer.busy is not None:
            layer.busy = timeline.is_playing_plain
        if isinstance(layer, GazeLayer):
            layer.sample = lambda t_s, below=None, layer=layer: _gaze_plain(layer, t_s)  # type: ignore[method-assign]
    return script


@pytest.mark.parametrize("path", sorted(SCRIPTS_DIR.glob("*.toml"))[:12], ids=lambda p: p.stem)
def test_scripts_sample_the_same_frames_with_the_fast_paths(path: object) -> None:
    fast = load_script(path)  # type: ignore[arg-type]
    plain = _plain(load_script(path))  # type: ignore[arg-type]
    rng = np.random.default_rng(44)
    end = max(fast.end_s, 1.0) + 2.0
    times = [k / 50 for k in range(int(end * 50))] + [float(t) for t in rng.uniform(-0.5, end, size=200)]
    for t in times:  # frame by frame, then random order (the layers are pure functions of time)
        a, b = fast.timeline.sample_aus(t), plain.timeline.sample_aus(t)
        assert list(a.items()) == list(b.items()), t


def _random_timeline(face_type: str, seed: int) -> Timeline:
    """Clips on several tracks that close the lids (the blink then reads them below it), gaze shifts,
    blinks and idle motion; the same timeline for the same seed."""
    rng = np.random.default_rng(seed)
    timeline = Timeline(face_type)  # type: ignore[arg-type]
    lids = ["AU43", "AU45", "AU45L", "AU5"] if face_type == "human" else ["AU15", "AU15L", "AU4", "AU3"]
    others = ["AU12", "AU1", "AU26", "AU61"] if face_type == "human" else ["AU1", "AU10", "AU12", "AU2"]
    for _ in range(10):
        names = rng.choice(lids + others, size=int(rng.integers(1, 4)), replace=False)
        pose = {str(a): float(rng.uniform(0.5, 1.0)) for a in names}
        d = float(rng.uniform(0.1, 1.5))
        timeline.play(EnvelopeClip(pose, Envelope(d / 2, d, d / 2)), float(rng.uniform(0, 10)),
                      track=str(rng.choice(["face", "gesture", "speech"])))  # fmt: skip
    gaze = GazeLayer(face_type)  # type: ignore[arg-type]
    for _ in range(4):
        gaze.look_at(float(rng.uniform(0, 10)), (float(rng.uniform(-500, 500)), 100.0, 1000.0))
    timeline.add_layer("gaze", gaze)
    timeline.add_layer("blink", BlinkLayer(face_type, seed, BlinkConfig(mean_interval_s=1.0)))  # type: ignore[arg-type]
    timeline.add_layer("idle", IdleLayer(face_type, seed, busy=timeline.is_playing))  # type: ignore[arg-type]
    return timeline


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_random_timelines_sample_the_same_frames_with_the_fast_paths(face_type: str) -> None:
    suppressed = 0
    for seed in range(6):
        fast = _random_timeline(face_type, seed)
        plain = _plain(Script("<random>", "", face_type, _random_timeline(face_type, seed), 12.0))  # type: ignore[arg-type]
        for t in [k / 50 for k in range(12 * 50)]:
            a, b = fast.sample_aus(t), plain.timeline.sample_aus(t)
            assert list(a.items()) == list(b.items()), (seed, t)
            blink = fast.layer("blink")
            suppressed += blink.closure(t) > 0 and "AU45" not in a and "AU15" not in a  # type: ignore[attr-defined]
    assert suppressed > 0  # the lids closed by a clip did hold a blink back: the blend below was read


def _channel_plain(layer: IdleLayer, name: str, t_s: float) -> float:
    """`IdleLayer.channel` knot by knot, as it was."""
    period = layer.config.head_period_s if name.startswith("head") else layer.config.eye_period_s
    x = max(0.0, t_s) / period
    k = int(math.floor(x))
    c0, c1, c2, c3 = (layer._knot(name, k + j) for j in range(4))
    return _bspline(c0, c1, c2, c3, x - k)


def test_idle_channels_equal_the_knot_by_knot_evaluation_in_any_query_order() -> None:
    rng = np.random.default_rng(45)
    for seed in range(5):
        fast, plain = IdleLayer("human", seed), IdleLayer("human", seed)
        for t in rng.uniform(-1.0, 60.0, size=300) * (rng.random() < 0.5 or 0.1):
            name = str(rng.choice(CHANNELS))
            assert fast.channel(name, float(t)) == _channel_plain(plain, name, float(t))


def _angles_plain(face_type: str, cfg: GazeConfig, *angles_deg: float) -> dict[str, float]:
    hy, hp, ey, ep, hr = angles_deg
    if face_type != "human":
        return angles_to_aus(face_type, cfg, hy, hp, ey, ep, hr)  # type: ignore[arg-type]
    out: dict[str, float] = {}
    out |= _split(hy / cfg.neck_limit_yaw_deg, "AU51", "AU52")
    out |= _split(hp / cfg.neck_limit_pitch_deg, "AU53", "AU54")
    out |= _split(hr / cfg.neck_limit_roll_deg, "AU55", "AU56")
    out |= _split(ey / cfg.eye_limit_yaw_deg, "AU61", "AU62")
    out |= _split(ep / cfg.eye_limit_pitch_deg, "AU63", "AU64")
    return out


def test_angles_to_aus_equals_the_pairwise_split() -> None:
    rng = np.random.default_rng(46)
    cfg = GazeConfig()
    for _ in range(2000):
        angles = [float(a) if rng.random() < 0.9 else 0.0 for a in rng.uniform(-90, 90, size=5)]
        got = angles_to_aus("human", cfg, *angles)
        assert repr(list(got.items())) == repr(list(_angles_plain("human", cfg, *angles).items()))
