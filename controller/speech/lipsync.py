"""The three ways to a lip-sync plan, end to end: text (synthesised), recorded speech with its transcript
(aligned), any audio (envelope).

An aligned recording carries the transcript check (``speech/align_check.py``): ``Speech.transcript_check``
says whether the transcript seems to be the text of the audio. A doubtful fit is a warning on the result;
a gross mismatch raises ``TranscriptMismatchError`` unless ``allow_mismatch`` (then the plan is made from
the alignment anyway, or from the audio's envelope when no alignment path fitted at all).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.align_check import TranscriptCheck
from servoface.controller.speech.audio import read_wav, to_float
from servoface.controller.speech.plan import DEFAULT_LEAD_S, LipSyncPlan, plan_from_visemes
from servoface.controller.speech.timing import visemes_from_phonemes


@dataclass(frozen=True)
class Speech:
    """Audio (mono float -1..1) with the lip-sync plan that goes with it; ``method``: text | aligned | envelope."""

    samples: NDArray[np.float64]
    rate_hz: int
    plan: LipSyncPlan
    method: str
    text: str = ""
    phonemes: tuple[tuple[str, float], ...] = ()  # (phoneme, start s) the plan was made from (text, aligned)
    transcript_check: TranscriptCheck | None = None  # recordings with a transcript: does it fit the audio?

    @property
    def duration_s(self) -> float:
        return len(self.samples) / self.rate_hz


def speech_from_text(
    text: str,
    *,
    voice: str = "en-us",
    rate_wpm: int | None = None,
    lead_s: float = DEFAULT_LEAD_S,
    intensity: float = 1.0,
) -> Speech:
    """Synthesise ``text`` with espeak-ng; the plan's visemes come from its own phoneme events."""
    from servoface.controller.speech.espeak import synthesize

    synth = synthesize(text, voice=voice, rate_wpm=rate_wpm)
    samples = to_float(synth.samples)
    segments = visemes_from_phonemes([(p.phoneme, p.t_s) for p in synth.phonemes], synth.duration_s)
    plan = plan_from_visemes(
        segments,
        audio_duration_s=synth.duration_s,
        samples=samples,
        sample_rate_hz=synth.sample_rate_hz,
        lead_s=lead_s,
        intensity=intensity,
    )
    events = tuple((p.phoneme, p.t_s) for p in synth.phonemes)
    return Speech(samples, synth.sample_rate_hz, plan, "text", text, events)


def speech_from_recording(
    audio: str | Path | tuple[NDArray[np.float64], int],
    transcript: str | None = None,
    *,
    lead_s: float = DEFAULT_LEAD_S,
    intensity: float = 1.0,
    allow_mismatch: bool = False,
) -> Speech:
    """Recorded speech: forced alignment when a transcript is given, else the causal envelope. The
    transcript is checked against the audio: see the module docstring for ``allow_mismatch``."""
    samples, rate = read_wav(audio) if isinstance(audio, str | Path) else (np.asarray(audio[0], float), int(audio[1]))
    from servoface.controller.speech.envelope import envelope_plan

    if transcript is None:
        return Speech(samples, rate, envelope_plan(samples, rate, lead_s=lead_s), "envelope")
    from servoface.controller.speech.align_check import checked_alignment

    alignment, check = checked_alignment(samples, rate, transcript, allow_mismatch=allow_mismatch)
    if alignment is None:  # no path fitted and the caller allowed it: the mouth follows the sound
        plan = envelope_plan(samples, rate, lead_s=lead_s)
        return Speech(samples, rate, plan, "envelope", transcript, transcript_check=check)
    phones = alignment.phones
    segments = visemes_from_phonemes([(p.phone, p.start_s) for p in phones], len(samples) / rate, alphabet="arpabet")
    plan = plan_from_visemes(
        segments,
        audio_duration_s=len(samples) / rate,
        samples=samples,
        sample_rate_hz=rate,
        lead_s=lead_s,
        intensity=intensity,
    )
    events = tuple((p.phone, p.start_s) for p in phones)
    return Speech(samples, rate, plan, "aligned", transcript, events, check)
