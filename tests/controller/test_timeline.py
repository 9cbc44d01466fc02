"""Easing and envelopes, Barker's timing model (golden 2.34 s example), sequences, tracks and blending."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from servoface.controller.errors import FrameError, TimelineError
from servoface.controller.timeline import (
    EASINGS,
    BlendPolicy,
    BlendRule,
    Envelope,
    EnvelopeClip,
    Expression,
    Movement,
    Timeline,
    ease_in_out,
    easing_by_name,
    linear,
    min_jerk,
    sequence,
)

P1 = {"AU12": 0.60, "AU11": 0.40, "AU20": 0.20}
P2 = {"AU12": 0.80, "AU11": 0.75, "AU20": 0.40}
P3 = {"AU12": 0.10, "AU11": 0.05, "AU20": 0.07}


def barker_e() -> Expression:
    return Expression.from_percent("E", 2.34, [(10, P1), (80, P2), (10, P3)])


# -- easing and envelopes -------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(EASINGS))
def test_easing_endpoints_and_monotone(name: str) -> None:
    fn = easing_by_name(name)
    u = np.linspace(0.0, 1.0, 201)
    values = [fn(float(x)) for x in u]
    assert values[0] == 0.0 and values[-1] == 1.0
    assert all(b >= a - 1e-12 for a, b in zip(values, values[1:], strict=False))
    assert fn(-0.5) == 0.0 and fn(1.5) == 1.0


def test_min_jerk_known_values() -> None:
    assert min_jerk(0.5) == pytest.approx(0.5)
    assert min_jerk(0.25) == pytest.approx(10 / 64 - 15 / 256 + 6 / 1024)  # 0.103515625
    assert min_jerk(0.75) == pytest.approx(1 - 0.103515625)
    h = 1e-6  # zero velocity at both ends, peak velocity 1.875 at the middle
    assert (min_jerk(h) - min_jerk(0)) / h == pytest.approx(0.0, abs=1e-5)
    assert (min_jerk(1) - min_jerk(1 - h)) / h == pytest.approx(0.0, abs=1e-5)
    assert (min_jerk(0.5 + h) - min_jerk(0.5 - h)) / (2 * h) == pytest.approx(1.875, rel=1e-6)
    assert ease_in_out(0.5) == pytest.approx(0.5) and linear(0.3) == pytest.approx(0.3)


def test_unknown_easing_names_the_field() -> None:
    with pytest.raises(TimelineError, match=r"movements\[0\]\.easing: unknown easing 'bouncy'; expected one of"):
        easing_by_name("bouncy", field="movements[0].easing")


def test_envelope_shape() -> None:
    env = Envelope(onset_s=0.2, apex_s=0.5, offset_s=0.3, easing=min_jerk)
    assert env.duration_s == pytest.approx(1.0)
    assert env.gain(-0.1) == 0.0 and env.gain(0.0) == 0.0 and env.gain(1.0) == 0.0
    assert env.gain(0.1) == pytest.approx(0.5)  # min-jerk midpoint of the onset
    assert env.gain(0.2) == 1.0 and env.gain(0.6) == 1.0
    assert env.gain(0.85) == pytest.approx(0.5)
    t = np.linspace(0, 0.2, 50)
    rise = [env.gain(float(x)) for x in t]
    assert all(b >= a for a, b in zip(rise, rise[1:], strict=False))
    t = np.linspace(0.7, 1.0, 50)
    fall = [env.gain(float(x)) for x in t]
    assert all(b <= a for a, b in zip(fall, fall[1:], strict=False))
    with pytest.raises(TimelineError, match="onset_s: expected a finite duration"):
        Envelope(-1.0, 0.1, 0.1)


def test_envelope_clip_scales_a_pose_and_ends_at_nothing() -> None:
    tl = Timeline("human")
    clip = EnvelopeClip({"AU1": 0.8, "AU2": 0.6}, Envelope(0.1, 0.2, 0.1))
    tl.play(clip, 1.0, track="gesture")
    assert tl.sample_aus(1.05) == pytest.approx({"AU1": 0.4, "AU2": 0.3})
    assert tl.sample_aus(1.2) == pytest.approx({"AU1": 0.8, "AU2": 0.6})
    assert tl.sample_aus(2.0) == {}


# -- Barker ---------------------------------------------------------------------------------------------
def test_barker_golden_example_key_times() -> None:
    assert barker_e().key_times_s() == pytest.approx([0.234, 2.106, 2.34])


def test_barker_golden_example_lands_every_pose_on_time() -> None:
    p0 = {"AU12": 0.2, "AU4": 0.5}  # the face before E: AU4 is not in E, so it goes to 0 during P0 -> P1
    clip = barker_e().clip()
    assert clip.sample(0.0, p0) == pytest.approx({**p0, "AU11": 0.0, "AU20": 0.0})
    assert clip.sample(0.234, p0) == pytest.approx({**P1, "AU4": 0.0})
    assert clip.sample(2.106, p0) == pytest.approx({**P2, "AU4": 0.0})
    assert clip.sample(2.34, p0) == pytest.approx({**P3, "AU4": 0.0})
    # piecewise linear in between (Barker: no easing)
    assert clip.sample(0.117, p0)["AU12"] == pytest.approx(0.4)
    assert clip.sample(0.117, p0)["AU4"] == pytest.approx(0.25)
    assert clip.sample(0.234 + 1.872 / 4, p0)["AU11"] == pytest.approx(0.40 + 0.35 / 4)
    assert clip.sample(10.0, p0) == pytest.approx({**P3, "AU4": 0.0})  # holds the last pose


def test_barker_on_a_timeline_is_time_driven() -> None:
    tl = Timeline("human")
    tl.play(barker_e().clip(), at_s=1.0)
    assert tl.sample(0.5).aus == {}
    assert dict(tl.sample(1.0 + 2.106).aus) == pytest.approx(P2)
    # sampling is pure: any order, any repetition, same answer (a late frame is skipped, never lagged)
    a = [tl.sample_aus(t) for t in (3.0, 1.2, 2.5, 1.2)]
    assert a[1] == a[3] and a[0] == tl.sample_aus(3.0)


def test_shares_must_sum_to_one_and_be_fractions() -> None:
    with pytest.raises(TimelineError, match=r"E\.movements: shares must sum to 1 \(100 %\), got 0.9"):
        Expression.from_percent("E", 1.0, [(10, P1), (80, P2)])
    with pytest.raises(TimelineError, match="share: expected a fraction 0..1"):
        Movement(P1, 1.5)
    with pytest.raises(TimelineError, match="E.duration_s"):
        Expression("E", 0.0, (Movement(P1, 1.0),))
    with pytest.raises(TimelineError, match="AU12: expected a finite"):
        Movement({"AU12": math.nan}, 1.0)


def test_retime_by_scaling_duration() -> None:
    assert barker_e().scaled(4.68).key_times_s() == pytest.approx([0.468, 4.212, 4.68])


def test_onset_apex_offset_as_movements() -> None:
    e = Expression.envelope("flash", {"AU1": 0.8}, 0.2, 0.6, 0.2, easing=linear)
    clip = e.clip()
    assert clip.sample(0.1, {})["AU1"] == pytest.approx(0.4)
    assert clip.sample(0.5, {})["AU1"] == pytest.approx(0.8)
    assert clip.sample(0.9, {})["AU1"] == pytest.approx(0.4)
    assert clip.end_pose({}) == {"AU1": 0.0}


# -- sequences ------------------------------------------------------------------------------------------
def test_sequence_starts_from_the_current_face_then_chains() -> None:
    smile = Expression("smile", 1.0, (Movement({"AU12": 0.8}, 1.0),))
    frown = Expression("frown", 1.0, (Movement({"AU15": 0.6}, 1.0),))
    tl = Timeline("human")
    tl.play(Expression("hold", 0.5, (Movement({"AU4": 0.6}, 1.0),)).clip(), 0.0)
    tl.play(sequence([smile, frown]), at_s=1.0)
    # at the start of the sequence the face is where the previous clip left it
    assert tl.sample_aus(1.0) == pytest.approx({"AU4": 0.6})
    assert tl.sample_aus(1.5) == pytest.approx({"AU4": 0.3, "AU12": 0.4})
    # the second expression starts from the end of the first
    assert tl.sample_aus(2.5) == pytest.approx({"AU12": 0.4, "AU15": 0.3})
    assert tl.sample_aus(3.0) == pytest.approx({"AU15": 0.6})


def test_a_clip_started_midway_continues_without_a_jump() -> None:
    tl = Timeline("human")
    tl.play(Expression("a", 2.0, (Movement({"AU12": 1.0}, 1.0),)).clip(), 0.0)
    tl.play(Expression("b", 1.0, (Movement({"AU12": 0.0}, 1.0),)).clip(), 1.0)
    assert tl.sample_aus(1.0 - 1e-9)["AU12"] == pytest.approx(0.5, abs=1e-6)
    assert tl.sample_aus(1.0)["AU12"] == pytest.approx(0.5)
    assert tl.sample_aus(1.5)["AU12"] == pytest.approx(0.25)


def test_initial_pose_and_explicit_from_pose() -> None:
    tl = Timeline("human", initial_pose={"AU12": 0.5})
    tl.play(Expression("x", 1.0, (Movement({"AU6": 1.0}, 1.0),)).clip(), 0.0)
    assert tl.sample_aus(0.0) == pytest.approx({"AU12": 0.5})
    tl.play(Expression("y", 1.0, (Movement({}, 1.0),)).clip(), 2.0, from_pose={"AU1": 1.0})
    assert tl.sample_aus(2.5) == pytest.approx({"AU1": 0.5})


def test_play_checks_the_clip_against_the_face_now() -> None:
    tl = Timeline("human")
    with pytest.raises(TimelineError, match=r"track face: .*AU7: FACS intensity -0.5 is out of range"):
        tl.play(Expression("bad", 1.0, (Movement({"AU7": -0.5}, 1.0),)).clip())
    with pytest.raises(TimelineError, match="AU3 is not an AU of the human face"):
        tl.play(Expression("bad", 1.0, (Movement({"AU3": 0.5}, 1.0),)).clip())
    assert tl.end_s == 0.0  # nothing was placed


# -- blending -------------------------------------------------------------------------------------------
def _two_tracks(policy: BlendPolicy, face: str = "human") -> Timeline:
    tl = Timeline(face, blend=policy)  # type: ignore[arg-type]
    return tl


def test_blend_max_is_the_default_for_face_aus() -> None:
    policy = BlendPolicy.for_face("human")
    out = policy.blend([("face", {"AU12": 0.6, "AU45": 0.2}), ("blink", {"AU45": 1.0}), ("gesture", {"AU12": 0.3})])
    assert out == {"AU12": 0.6, "AU45": 1.0}


def test_blend_max_keeps_the_sign_of_the_larger_magnitude_for_dfacs() -> None:
    policy = BlendPolicy.for_face("dog")
    assert policy.blend([("face", {"AU5": 0.2}), ("gesture", {"AU5": -0.8})]) == {"AU5": -0.8}


def test_blend_sum_is_clamped() -> None:
    policy = BlendPolicy.for_face("human")
    assert policy.rule_for("AU26") is BlendRule.SUM and policy.rule_for("AU61") is BlendRule.SUM
    out = policy.blend([("face", {"AU26": 0.7}), ("speech", {"AU26": 0.5})], 0.0, 1.0)
    assert out == {"AU26": 1.0}
    assert policy.blend([("face", {"AU26": 0.2}), ("speech", {"AU26": 0.3})])["AU26"] == pytest.approx(0.5)


def test_blend_override_takes_the_highest_priority_track() -> None:
    policy = BlendPolicy.for_face("human", rules={"AU12": "override"}, priority=["speech", "face"])
    out = policy.blend([("face", {"AU12": 0.9}), ("speech", {"AU12": 0.1})])
    assert out == {"AU12": 0.1}
    # a track that does not provide the AU does not override it
    assert policy.blend([("face", {"AU12": 0.9}), ("speech", {"AU26": 0.1})])["AU12"] == 0.9
    # a rule on AU12 covers AU12L unless AU12L has its own
    assert policy.rule_for("AU12L") is BlendRule.OVERRIDE


def test_blend_nets_opposite_directions_of_one_joint() -> None:
    policy = BlendPolicy.for_face("human")
    out = policy.blend([("gaze", {"AU61": 0.3, "AU62": 0.0}), ("idle", {"AU61": 0.0, "AU62": 0.05})])
    assert out["AU61"] == pytest.approx(0.25) and out["AU62"] == 0.0


def test_bad_blend_rule_is_named() -> None:
    with pytest.raises(TimelineError, match="blend.AU12: unknown blend rule 'average'"):
        BlendPolicy.for_face("human", rules={"AU12": "average"})


def test_parallel_tracks_on_a_timeline() -> None:
    tl = Timeline("human")
    tl.play(Expression("smile", 1.0, (Movement({"AU12": 0.6, "AU26": 0.2}, 1.0),)).clip(), 0.0)
    tl.play(Expression("talk", 1.0, (Movement({"AU26": 0.3}, 1.0),)).clip(), 0.0, track="speech")
    tl.play(EnvelopeClip({"AU12": 0.9}, Envelope(0.0, 0.5, 0.0)), 1.0, track="gesture")
    assert tl.sample_aus(1.0) == pytest.approx({"AU12": 0.9, "AU26": 0.5})
    assert tl.sample_aus(2.0) == pytest.approx({"AU12": 0.6, "AU26": 0.5})
    frames = list(tl.frames(10.0, 0.0, 1.0))
    assert [f.t_s for f in frames] == pytest.approx([k / 10 for k in range(11)])
    assert tl.is_playing(0.5) and not tl.is_playing(5.0)


def test_a_layer_producing_an_invalid_value_is_a_frame_error() -> None:
    class Broken:
        def sample(self, t_s: float, below: object) -> dict[str, float]:
            return {"AU99": 0.5}

    tl = Timeline("human")
    tl.add_layer("broken", Broken())
    with pytest.raises(FrameError, match="AU99"):
        tl.sample(0.0)
    with pytest.raises(TimelineError, match="layer 'broken' already exists"):
        tl.add_layer("broken", Broken())


@given(
    st.lists(
        st.tuples(
            st.sampled_from(["face", "speech", "gaze", "idle", "gesture"]),
            st.dictionaries(st.sampled_from(["AU12", "AU26", "AU61", "AU62", "AU45"]), st.floats(0, 1)),
        ),
        max_size=5,
    )
)
def test_property_blending_stays_in_range(contribs: list[tuple[str, dict[str, float]]]) -> None:
    out = BlendPolicy.for_face("human").blend(contribs, 0.0, 1.0)
    assert all(0.0 <= v <= 1.0 for v in out.values())
    assert not (out.get("AU61", 0) > 0 and out.get("AU62", 0) > 0)  # one direction per joint
    provided = {au for _, aus in contribs for au in aus}
    assert set(out) == provided


def test_library_clip_for_both_faces() -> None:
    from servoface.controller.timeline.library import library_clip

    happy = library_clip("human", "happiness", onset_s=0.2, apex_s=1.0, offset_s=0.2)
    assert happy.duration_s == pytest.approx(1.4)
    assert happy.sample(0.7, {})["AU12"] > 0.5 and happy.end_pose({})["AU12"] == 0.0
    anger = library_clip("dog", "anger")
    firsts = {au: moves[0][0] for au, moves in anger.onsets().items() if moves}
    assert sorted(firsts, key=firsts.__getitem__)[:3] == ["AU14", "AU4", "AU1"]
    with pytest.raises(TimelineError, match="expression 'glee' is not in the human library"):
        library_clip("human", "glee")


@given(
    st.lists(
        st.tuples(
            st.floats(0.0, 5.0),  # start
            st.floats(0.2, 2.0),  # duration
            st.dictionaries(st.sampled_from(["AU1", "AU4", "AU12", "AU26"]), st.floats(0, 1), max_size=3),
            st.floats(0.1, 0.9),  # share of the first movement (> 0: no cut)
        ),
        min_size=1,
        max_size=5,
    )
)
def test_property_a_face_track_never_jumps_at_clip_boundaries(clips: list) -> None:  # type: ignore[type-arg]
    tl = Timeline("human")
    for start, duration, pose, share in clips:
        tl.play(Expression("x", duration, (Movement(pose, share), Movement(pose, 1 - share))).clip(), start)
    for start, *_ in clips:
        before, after = tl.sample_aus(start - 1e-7), tl.sample_aus(start)
        for au in set(before) | set(after):
            assert abs(before.get(au, 0.0) - after.get(au, 0.0)) < 1e-4, (au, start)
