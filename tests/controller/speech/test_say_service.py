"""`Face.say` is a head-service speech track, and the mouth follows the audio clock (the monotonic clock
when no device plays, a device's DAC times when one does), checked on the emulated head."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.au_names import head_au_names
from servoface.controller.face import Face
from servoface.controller.service.handles import Status
from servoface.controller.speech.jaw_budget import JawBudget
from servoface.controller.speech.lipsync import speech_from_text
from servoface.controller.speech.playback import (
    AudioClockedClip,
    DeviceAudioClock,
    MonotonicAudioClock,
)
from servoface.controller.speech.say import say_on_face
from servoface.controller.speech.visemes import mouth_aus


@pytest.mark.slow
def test_face_say_plays_on_the_service_speech_track() -> None:
    with Face.open("human", emulate=True) as face:
        face.hold(0.1)
        events = face.service.subscribe("playback", maxlen=256)
        perf = face.say("Hello there, nice to meet you.")
        seen = [(e.kind, e.track, e.status) for e in events.drain()]
        events.close()
    speech = [s for k, t, s in seen if t == "speech"]
    assert Status.RUNNING in speech and Status.DONE in speech, seen
    assert not [x for x in seen if x[1] == "face"], f"say must not use the face track: {seen}"
    jaw = [t.aus.get("AU26", 0.0) for t in perf.traces]
    assert max(jaw) > 0.1, "the jaw did not open while speaking"


def test_the_monotonic_clock_is_the_clips_own_time() -> None:
    speech = speech_from_text("Hi.")
    clip = speech.plan.clip("human", mouth_aus("human"))
    t0, latency, lead = 100.0, 0.012, speech.plan.audio_start_s
    clock = MonotonicAudioClock(t0 + lead + latency)
    timed = AudioClockedClip(clip, clock, t0, latency, lead, clip.duration_s + 0.15)
    for t in np.linspace(0.0, clip.duration_s - 0.01, 40):
        assert timed.mouth_time_s(float(t)) == pytest.approx(float(t), abs=1e-9)
    assert timed.sample(clip.duration_s + 0.05, {}) == {}, "past its end the clip provides nothing"


def test_a_device_clock_drags_the_mouth_with_it() -> None:
    # a device that started 40 ms late and whose crystal runs 1 % fast: the mouth follows its DAC times
    rate, sched = 16000, 50.0
    clock = DeviceAudioClock(rate, sched)
    assert clock.position_s(sched + 0.3) == pytest.approx(0.3), "before the first buffer: the schedule"
    for k in range(0, 50):
        n = k * 256
        clock.anchor(n, sched + 0.040 + (n / rate) / 1.01)
    pos, at = clock.anchors[-1]
    assert clock.position_s(at + 0.005) == pytest.approx(pos + 0.005)
    offsets = clock.offsets_s()
    assert offsets[0] == pytest.approx(0.040) and offsets[-1] < 0.040  # fast: it catches up on the schedule
    speech = speech_from_text("Hi.")
    clip = speech.plan.clip("human", mouth_aus("human"))
    timed = AudioClockedClip(clip, clock, sched - 0.05, 0.0, 0.05, clip.duration_s)
    local = at - (sched - 0.05)
    assert timed.mouth_time_s(local) == pytest.approx(pos + 0.05, abs=1e-9)


@pytest.mark.slow
def test_on_the_emulated_head_the_wire_follows_a_late_device() -> None:
    """The same speech with a device clock 60 ms behind its schedule: every frame's jaw AU is the clip's
    value 60 ms earlier on the mouth clock (what the speaker is playing then), not the service's time."""
    speech = speech_from_text("Bob bought a big blue balloon.")
    with Face.open("human", emulate=True) as face:
        face.hold(0.1)
        svc = face.service
        allowed = head_au_names(face.head) & mouth_aus("human")
        plan, _ = JawBudget().apply(speech.plan, 0.0)
        clip = plan.clip("human", allowed)
        at_s = svc.now_s() + 0.1
        start = svc.clock.to_monotonic_s(at_s)
        clock = DeviceAudioClock(speech.rate_hz, start + plan.audio_start_s)
        clock.anchor(0, start + plan.audio_start_s + 0.060)  # the device reports: sample 0 plays 60 ms late
        timed = AudioClockedClip(clip, clock, start, 0.0, plan.audio_start_s, plan.duration_s + 0.2)
        perf = face._perform(lambda s: s.speak(timed, at_s=at_s), timed.duration_s, track="speech")  # noqa: SLF001
    frames = [t for t in perf.traces if 0.2 < t.t_s < plan.audio_end_s - 0.1]
    assert len(frames) >= 3, "too few frames (a loaded machine skips frames, but not all)"
    errors = [abs(t.aus.get("AU26", 0.0) - clip.sample(t.t_s - 0.060, {}).get("AU26", 0.0)) for t in frames]
    assert max(errors) < 1e-6, "the jaw did not follow the device's clock"
    grid = np.arange(0.2, plan.audio_end_s - 0.1, 0.01)
    apart = [abs(clip.sample(t, {}).get("AU26", 0.0) - clip.sample(t - 0.060, {}).get("AU26", 0.0)) for t in grid]
    assert max(apart) > 0.05, "the test speech does not tell the two clocks apart"
    assert all(s == pytest.approx(-0.060, abs=1e-9) for s in list(timed.shifts)[5:-5])


@pytest.mark.slow
def test_spoken_run_reports_the_monotonic_clock_without_a_device() -> None:
    speech = speech_from_text("Good morning.")
    with Face.open("human", emulate=True) as face:
        face.hold(0.1)
        run = say_on_face(face, speech, audio_out=False)
    assert run.clock == "monotonic"
    assert run.shifts_s and max(abs(s) for s in run.shifts_s) < 1e-9
    assert run.budget is not None and run.budget.min_scale == 1.0, "a short sentence is within the jaw budget"
