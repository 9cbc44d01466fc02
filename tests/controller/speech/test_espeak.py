"""Synthesis through libespeak-ng: real audio, phoneme events in the audio's clock."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.espeak import synthesize


def test_synthesis_gives_audio_and_ordered_phoneme_events_inside_it() -> None:
    s = synthesize("Hello world, my name is servo face.")
    assert s.sample_rate_hz == 22050 and 1.5 < s.duration_s < 4.0
    assert np.abs(s.samples.astype(float)).max() > 3000  # real speech, not silence
    times = [p.t_s for p in s.phonemes]
    assert times == sorted(times) and 0 <= times[0] and times[-1] <= s.duration_s + 0.01
    names = [p.phoneme.strip("',") for p in s.phonemes]
    assert "m" in names and "f" in names and "w" in names
    assert len(s.words) == 7


def test_phoneme_events_sit_on_the_sound_they_name() -> None:
    """A vowel's event lands where the audio is loud; the pause events where it is quiet."""
    s = synthesize("Ah. Ah.")
    x = s.samples.astype(float) / 32768.0
    rate = s.sample_rate_hz

    def rms_after(t_s: float) -> float:
        i = int(t_s * rate)
        return float(np.sqrt(np.mean(x[i + int(0.02 * rate) : i + int(0.06 * rate)] ** 2)))

    vowels = [p for p in s.phonemes if p.phoneme.strip("'") in ("A:", "a", "a:")]
    assert vowels, [p.phoneme for p in s.phonemes]
    assert all(rms_after(v.t_s) > 0.02 for v in vowels)


@pytest.mark.parametrize("bad", ["", "   ", None, 3, "x" * 20_001])
def test_bad_text_is_refused_with_the_field(bad: object) -> None:
    with pytest.raises(SpeechError, match="text"):
        synthesize(bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("voice", ["no-such-voice-xyz", "en us; rm", "", "é"])
def test_bad_voice_is_refused(voice: str) -> None:
    with pytest.raises(SpeechError, match="voice"):
        synthesize("hello", voice=voice)


def test_rate_out_of_range_is_refused() -> None:
    with pytest.raises(SpeechError, match="rate_wpm"):
        synthesize("hello", rate_wpm=5000)


def test_a_rate_or_pitch_does_not_stay_for_the_next_caller() -> None:
    text = "Bob bought a big blue balloon."
    plain = synthesize(text)
    synthesize(text, rate_wpm=300, pitch=90)
    again = synthesize(text)
    assert again.duration_s == pytest.approx(plain.duration_s, rel=0.03)
