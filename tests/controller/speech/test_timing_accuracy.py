"""Lip-sync timing against espeak-ng's own phoneme events (the ground truth), over a 22-sentence corpus.

- text path: the plan's viseme onsets ARE espeak's events (exact by construction);
- forced alignment (pocketsphinx) of the synthesised audio with its text: median onset error <= 20 ms and
  >= 85 % within 50 ms (issue "Speech", must show);
- envelope path (no transcript): onsets of jaw opening against the onsets of spoken runs, reported.
"""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.speech.audio import to_float
from servoface.controller.speech.envelope import envelope_plan
from servoface.controller.speech.espeak import synthesize
from servoface.controller.speech.lipsync import speech_from_recording, speech_from_text
from servoface.controller.speech.timing import onsets, visemes_from_phonemes

from tests.controller.speech.corpus import SENTENCES


def _truth(text: str) -> tuple[list[tuple[str, float]], object]:
    s = synthesize(text)
    segs = visemes_from_phonemes([(p.phoneme, p.t_s) for p in s.phonemes], s.duration_s)
    return onsets(segs), s


def _errors(truth: list[tuple[str, float]], estimate: list[tuple[str, float]]) -> list[float]:
    """Per true onset: distance to the nearest estimated onset of the same viseme (any viseme if none)."""
    out = []
    for viseme, t in truth:
        same = [e for v, e in estimate if v == viseme] or [e for _, e in estimate]
        out.append(min(abs(e - t) for e in same))
    return out


def test_corpus_is_large_enough() -> None:
    assert len(SENTENCES) >= 20


def test_text_path_onsets_are_espeaks_events() -> None:
    """The plan of a synthesised text is made from the phoneme events of the very audio it plays with:
    its viseme onsets are those events, to the sample (espeak-ng's own timing varies by a few ms from one
    synthesis to the next, so the comparison is within one synthesis)."""
    for text in SENTENCES[:5]:
        speech = speech_from_text(text)
        truth = onsets(visemes_from_phonemes(list(speech.phonemes), speech.duration_s))
        assert onsets(list(speech.plan.segments)) == truth
        assert len(truth) >= 8


@pytest.mark.slow
def test_forced_alignment_onsets_match_espeak_events() -> None:
    errors: list[float] = []
    for text in SENTENCES:
        truth, s = _truth(text)
        speech = speech_from_recording((to_float(s.samples), s.sample_rate_hz), text)  # type: ignore[attr-defined]
        assert speech.method == "aligned"
        errors += _errors(truth, onsets(list(speech.plan.segments)))
    e = np.array(errors)
    median_ms, within = float(np.median(e) * 1e3), float(np.mean(e <= 0.05))
    print(
        f"forced alignment over {len(SENTENCES)} sentences, {len(e)} onsets: median {median_ms:.1f} ms, "
        f"{within:.1%} within 50 ms"
    )
    assert median_ms <= 20.0
    assert within >= 0.85


@pytest.mark.slow
def test_envelope_jaw_opens_with_the_spoken_runs() -> None:
    """The jaw (envelope path) opens at each spoken run's start (after a pause) and is near closed in
    the pauses between sentences."""
    errors = []
    for text in SENTENCES[:8]:
        s = synthesize(text + " " + text)
        x, rate = to_float(s.samples), s.sample_rate_hz
        plan = envelope_plan(x, rate)
        open_ = plan.feature("open")
        t = plan.times_s
        segs = visemes_from_phonemes([(p.phoneme, p.t_s) for p in s.phonemes], s.duration_s)
        runs = [
            seg.start_s for i, seg in enumerate(segs) if seg.viseme != "sil" and (i == 0 or segs[i - 1].viseme == "sil")
        ]
        for start in runs:
            after = np.nonzero((t >= start - 0.05) & (open_ > 0.15))[0]
            assert len(after), f"jaw never opened after {start:.2f} s in {text!r}"
            errors.append(t[after[0]] - start)
        pauses = [seg for seg in segs if seg.viseme == "sil" and seg.duration_s > 0.15 and seg.start_s > 0.2]
        for p in pauses:
            inside = (t > p.start_s + 0.1) & (t < p.end_s - 0.02)
            if inside.any():
                assert open_[inside].min() < 0.1, f"jaw stays open through the pause at {p.start_s:.2f} s"
    e = np.abs(np.array(errors))
    print(
        f"envelope: spoken-run onsets {len(e)}: median {np.median(e) * 1e3:.0f} ms, "
        f"{np.mean(e <= 0.05):.0%} within 50 ms"
    )
    assert np.median(e) <= 0.06
