"""A script's say cues on a head go through the head service's speech slot (`HeadService.speak`), as
`Face.say` does; the script itself plays on the face track with its say clips silent."""

from __future__ import annotations

from typing import Any

import pytest
from servoface.controller.script import parse_script
from servoface.controller.script_say import SayClip, say_cues, without_say
from servoface.controller.speech.visemes import mouth_aus

SAY = """
[script]
face = "human"

[[play]]
at_s = 0.0
library = "happiness"

[[play]]
at_s = 0.5
say = "Hello, nice to meet you."
"""


def test_say_cues_and_the_script_without_them() -> None:
    script = parse_script(SAY, source="say.toml")
    (cue,) = say_cues(script)
    assert (cue.at_s, cue.track, cue.text, cue.voice) == (0.5, "speech", "Hello, nice to meet you.", "en-us")
    muted = without_say(script)
    assert muted.end_s == script.end_s and muted.title == script.title
    (placed,) = [p for p in script.timeline.layer("speech").items]  # type: ignore[attr-defined]
    assert isinstance(placed.clip, SayClip)
    mouth = mouth_aus("human")
    talked = False
    for k in range(60):
        t = k * 0.05
        full, quiet = script.sample(t).aus, muted.sample(t).aus
        assert {au: v for au, v in full.items() if au not in mouth} == {
            au: v for au, v in quiet.items() if au not in mouth
        }, t  # the rest of the face is the same
        assert quiet.get("AU26", 0.0) == 0.0, t  # the jaw is not the script's any more
        talked |= full.get("AU26", 0.0) > 0.3
    assert talked, "the script's own say clip opens the jaw (studio scrubbing, previews)"
    assert say_cues(muted) == []


@pytest.mark.slow
def test_face_play_speaks_the_cue_on_the_speech_track(monkeypatch: pytest.MonkeyPatch) -> None:
    from servoface.controller.face import Face
    from servoface.controller.service import HeadService
    from servoface.controller.service.handles import Status

    calls: list[tuple[Any, float | None]] = []
    real = HeadService.speak

    def speak(self: HeadService, what: Any, *, at_s: float | None = None, duration_s: float | None = None) -> Any:
        calls.append((what, at_s))
        return real(self, what, at_s=at_s, duration_s=duration_s)

    monkeypatch.setattr(HeadService, "speak", speak)
    script = parse_script(SAY, source="say.toml")
    with Face.open("human", emulate=True) as face:
        events = face.service.subscribe("playback", maxlen=256)
        perf = face.play(script)
        seen = [(e.track, e.status) for e in events.drain()]
        events.close()
    assert len(calls) == 1 and calls[0][1] is not None, calls
    assert calls[0][0].clock.name in ("monotonic", "device")
    assert ("speech", Status.RUNNING) in seen and ("speech", Status.DONE) in seen, seen
    assert ("face", Status.DONE) in seen, seen
    assert perf.traces[0].t_s < 0.1, "the run's frames are timed from the script's start"
    assert sum(1 for t in perf.traces if t.t_s < 0.45) >= 5, "the frames before the cue are the run's too"
    jaw = [t.aus.get("AU26", 0.0) for t in perf.traces]
    assert max(jaw) > 0.3, "the jaw did not open"
    assert min(t.aus.get("AU12", 0.0) for t in perf.traces if 1.0 <= t.t_s <= 1.8) > 0.5, "the smile stays"


@pytest.mark.slow
def test_a_script_with_a_sound_file_plays_it_and_its_mouth_on_the_speech_track(
    tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What `servoface say --out` writes (speech.wav + speech.toml, the mouth keys on the script's speech
    track) played back: the sound from audio_start_s, the speech track's keys on the service's speech track
    timed by the sound's clock, the face track without them."""
    from servoface.controller.face import Face
    from servoface.controller.script import load_script
    from servoface.controller.service import HeadService
    from servoface.controller.speech.lipsync import speech_from_text
    from servoface.controller.speech.say import write_outputs
    from servoface.controller.speech.script_play import play_script_speaking, prepare, speaks

    speech = speech_from_text("Bob bought a big blue balloon.")
    _, path = write_outputs(speech, "human", tmp_path)
    script = load_script(path)
    assert speaks(script) and say_cues(script) == []
    ready = prepare(script)
    assert ready.audio is not None and len(ready.audio[0]) == len(speech.samples)
    calls: list[Any] = []
    real = HeadService.speak

    def speak(self: HeadService, what: Any, *, at_s: float | None = None, duration_s: float | None = None) -> Any:
        calls.append(what)
        return real(self, what, at_s=at_s, duration_s=duration_s)

    monkeypatch.setattr(HeadService, "speak", speak)
    quiet = without_say(script, tracks=frozenset({"speech"}))
    assert all(quiet.sample(k * 0.05).aus.get("AU26", 0.0) == 0.0 for k in range(60)), "muted: no jaw keys"
    with Face.open("human", emulate=True) as face:
        spoken = play_script_speaking(face, script, prepared=ready)
    assert len(calls) == 1 and calls[0].clock.name in ("monotonic", "device"), calls
    assert spoken.audio is not None and spoken.audio.mouth and spoken.audio.name == "speech.wav"
    assert any(line.startswith("played speech.wav at ") for line in spoken.lines()), spoken.lines()
    jaw = [t.aus.get("AU26", 0.0) for t in spoken.performance.traces]
    assert max(jaw) > 0.3, "the jaw did not open"


def test_an_unreadable_sound_file_is_refused_before_the_port_is_opened(
    tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    from servoface.controller.cli import main

    script = tmp_path / "talk.toml"
    script.write_text('[script]\nface = "human"\naudio = "missing.wav"\n[[play]]\nat_s = 0.0\nlibrary = "happiness"\n')
    assert main(["play", str(script), "--port", "/dev/does-not-exist"]) == 2
    err = capsys.readouterr().err
    assert "script.audio" in err and "missing.wav" in err and "does-not-exist" not in err, err


@pytest.mark.slow
def test_duration_cuts_a_cue_mouth_and_sound_there() -> None:
    from servoface.controller.face import Face
    from servoface.controller.speech.script_play import play_script_speaking

    script = parse_script(SAY, source="say.toml")  # the cue talks from 0.5 s to ~2 s
    with Face.open("human", emulate=True) as face:
        spoken = play_script_speaking(face, script, duration_s=0.9)
    traces = spoken.performance.traces
    assert max(t.aus.get("AU26", 0.0) for t in traces if t.t_s < 0.9) > 0.1, "it started talking"
    after = [t.aus.get("AU26", 0.0) for t in traces if t.t_s > 0.95]  # the servos settling on the cut pose
    assert all(v == 0.0 for v in after), after
    # the run ends once a frame passes the gate whole: how many frames the jaw takes to close after the cut
    # (none after 0.95 s when the gate's caps let it shut at once) is the gate's business; the last frame is
    # at or after the cut, with the mouth shut
    last = max(traces, key=lambda t: t.t_s)
    assert last.t_s >= 0.9 - 1e-9 and last.aus.get("AU26", 0.0) == 0.0, (last.t_s, last.aus.get("AU26"))
    assert max(t.t_s for t in traces) < 0.9 + 2.5, "the run ended at the cut (+ settling)"
