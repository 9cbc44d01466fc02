"""The studio plays a script that speaks as `servoface play` does (real HTTP on loopback, the emulator's
side of the wire): its say cues on the head service's speech track, its sound file's mouth within the jaw
budget; a say cue on another track is refused naming the field."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from servoface.controller.service import HeadService

from tests.studio.conftest import StudioRig

SAY = """[script]
face = "human"
[[play]]
at_s = 0.0
library = "happiness"
[[play]]
at_s = 0.2
say = "Hello, nice to meet you."
"""


@pytest.fixture
def speaks(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """What reaches HeadService.speak (recorded, then spoken as ever)."""
    calls: list[Any] = []
    real = HeadService.speak

    def speak(self: HeadService, what: Any, *, at_s: float | None = None, duration_s: float | None = None) -> Any:
        calls.append(what)
        return real(self, what, at_s=at_s, duration_s=duration_s)

    monkeypatch.setattr(HeadService, "speak", speak)
    return calls


def _jaw_goals(rig: StudioRig) -> list[int]:
    jaw = rig.service.head.servo_ids["jaw"]
    return [g for _, sid, g in rig.chain.goal_writes() if sid == jaw]


def test_a_say_cue_played_in_the_studio_speaks_on_the_speech_track(studio: StudioRig, speaks: list[Any]) -> None:
    studio.wait_for(lambda: studio.service.last_trace is not None, what="a first frame")
    studio.chain.log.clear()
    r = studio.client.post("/api/play", json={"toml": SAY})
    assert r.status_code == 202, r.text
    assert len(speaks) == 1 and speaks[0].clock.name == "monotonic", speaks  # no sound card here
    studio.wait_for(
        lambda: studio.service.status().tracks["speech"].state == "running", what="the speech track talking"
    )
    studio.wait_for(lambda: studio.service.status().tracks["speech"].state == "empty", what="the cue's end")
    goals = _jaw_goals(studio)
    assert goals and max(goals) - min(goals) > 20, "the jaw did not talk on the wire"


def test_a_sound_file_script_saved_in_the_studio_plays_its_mouth_within_the_budget(
    studio: StudioRig, speaks: list[Any]
) -> None:
    from servoface.controller.speech.jaw_clip import JawScaledClip
    from servoface.controller.speech.lipsync import speech_from_text
    from servoface.controller.speech.say import write_outputs

    folder = Path(studio.server.studio.options.scripts_dir)
    write_outputs(speech_from_text("Bob bought a big blue balloon."), "human", folder)
    r = studio.client.post("/api/play", json={"name": "speech.toml"})
    assert r.status_code == 202, r.text
    assert len(speaks) == 1 and isinstance(speaks[0].clip, JawScaledClip), speaks


def test_a_say_cue_on_another_track_is_refused_by_the_studio(studio: StudioRig) -> None:
    bad = SAY.replace('say = "Hello', 'track = "narrator"\nsay = "Hello')
    r = studio.client.post("/api/play", json={"toml": bad})
    assert r.status_code == 422, r.text
    assert "play[1].track" in r.text, r.text
