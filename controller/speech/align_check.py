"""Is the transcript the text of the recording? A check on a forced alignment, so that a mistyped
transcript or the wrong audio file is reported instead of mouthed confidently.

The aligner always returns *some* timing when it finds a path, so the check compares it with what the same
acoustic model hears without the transcript: a free phone loop (pocketsphinx's allphone search with the
phone bigram its wheel ships, ``en-us-phone.lm.bin``) decodes the same audio. Two measures:

- **cost ratio** (goodness of pronunciation): the alignment's acoustic cost per frame (minus its log
  likelihood, pocketsphinx's log units) over the phone loop's. The loop picks its phones freely, so its
  cost is (nearly) a floor; the transcript's phones should come close to it. The ratio divides out how well
  the model fits the voice at all (synthetic or noisy speech costs more per frame, right transcript or wrong). The
  loop's cost is floored at ``MIN_LOOP_COST`` so that very clean audio does not inflate the ratio.
- **speech left in silence**: the share of the frames the phone loop decodes as a phone (speech) that the
  alignment puts in silence. A transcript that misses words leaves their speech in the silences between
  the words it has; the cost ratio alone misses this, silence models absorb speech cheaply.

Calibrated on espeak-ng speech (the 22 Harvard sentences of the timing corpus, 8 voices from 120 to 300
words/min, 88 recordings): the right transcript had a cost ratio of 1.02-2.25 and 0-10 % of its speech in
silence, and all 88 passed. Flagged: another sentence 88 of 88 (39 found no path; the rest ratio 2.39 or
more), the words shuffled 88 of 88, the first or last half of the words 174 of 176 (speech in silence 22 %
or more for the first half). One wrong word in eight is flagged about a third of the time. Verdicts:

- ``ok``: ratio <= ``RATIO_WARN`` and speech in silence <= ``SILENT_SPEECH_WARN``;
- ``suspect`` (a warning, the lip sync goes ahead): one of the two is above its threshold;
- ``mismatch`` (:class:`TranscriptMismatchError` unless the caller allows it): both are, or the ratio is
  above ``RATIO_GROSS``, or no path through the transcript fitted the audio at all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.align import DECODER_LOCK, ForcedAlignment, force_align, make_decoder
from servoface.controller.speech.errors import TranscriptMismatchError

RATIO_WARN = 2.35  # alignment cost per frame / phone loop's: right transcripts <= 2.25 in calibration
RATIO_GROSS = 2.8  # far beyond any right transcript: a different text
SILENT_SPEECH_WARN = 0.14  # share of the loop's speech frames aligned to silence: right <= 0.10
MIN_LOOP_COST = 10.0  # floor on the phone loop's cost per frame (log units; espeak voices: 13-29)

Verdict = Literal["ok", "suspect", "mismatch"]


@dataclass(frozen=True)
class TranscriptCheck:
    """How well the transcript fits the audio: the cost ratio (``nan`` when there was no alignment), the
    share of speech aligned to silence, the verdict, and the reasons (sentences) behind it."""

    verdict: Verdict
    cost_ratio: float
    silent_speech: float
    reasons: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.verdict == "ok"

    def message(self) -> str:
        """One paragraph for a person: what looks wrong, its likely cause and what to check."""
        if self.ok:
            return "the transcript fits the audio"
        what = "does not match" if self.verdict == "mismatch" else "may not match"
        return f"the transcript {what} the audio: " + "; ".join(self.reasons)


def phone_loop(pcm: bytes) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Free phone decode of 16 kHz 16-bit PCM: per 10 ms frame, its acoustic score (log units, a segment's
    score spread evenly over its frames) and whether a phone (not silence or noise) was heard. ``(n,)``."""
    import pocketsphinx

    lm = Path(pocketsphinx.get_model_path()) / "en-us-phone.lm.bin"
    with DECODER_LOCK:
        decoder = make_decoder()
        decoder.add_allphone_file("phone_loop", str(lm))  # type: ignore[attr-defined]
        decoder.activate_search("phone_loop")  # type: ignore[attr-defined]
        decoder.start_utt()  # type: ignore[attr-defined]
        decoder.process_raw(pcm, full_utt=True)  # type: ignore[attr-defined]
        decoder.end_utt()  # type: ignore[attr-defined]
        n = int(decoder.n_frames())  # type: ignore[attr-defined]
        logmath = decoder.get_logmath()  # type: ignore[attr-defined]
        segments = [(s.word, s.start_frame, s.end_frame, s.ascore) for s in decoder.seg()]  # type: ignore[attr-defined]
    score = np.zeros(n)
    speech = np.zeros(n, dtype=bool)
    for word, first, last, ascore in segments:
        a, b = max(int(first), 0), min(int(last) + 1, n)  # end_frame is inclusive
        if b <= a:
            continue
        # the binding hands out the probability (logmath.exp of the score); back to log units
        score[a:b] = logmath.log(max(float(ascore), 1e-300)) / (b - a)
        speech[a:b] = not (word == "SIL" or word.startswith(("+", "<")))
    return score, speech


def check_alignment(alignment: ForcedAlignment) -> TranscriptCheck:
    """Compare a forced alignment with a free phone decode of the same audio (see the module docstring)."""
    loop_score, loop_speech = phone_loop(alignment.pcm)
    n = min(alignment.n_frames, len(loop_score))
    silent = np.zeros(n, dtype=bool)
    aligned_score = 0.0
    for p in alignment.decoded:
        aligned_score += p.score
        if p.phone == "SIL":
            silent[max(p.start_frame, 0) : min(p.start_frame + p.n_frames, n)] = True
    aligned_cost = -aligned_score / max(alignment.n_frames, 1)
    loop_cost = max(-float(loop_score.sum()) / max(len(loop_score), 1), MIN_LOOP_COST)
    ratio = aligned_cost / loop_cost
    speech = loop_speech[:n]
    silent_speech = float(silent[speech].mean()) if speech.any() else 0.0
    return verdict_of(ratio, silent_speech)


def verdict_of(cost_ratio: float, silent_speech: float) -> TranscriptCheck:
    """The verdict and its reasons from the two measures (thresholds above)."""
    reasons = []
    poor_fit = cost_ratio > RATIO_WARN
    left_out = silent_speech > SILENT_SPEECH_WARN
    if poor_fit:
        reasons.append(
            f"its sounds fit the recording poorly (acoustic cost {cost_ratio:.2f} x a free phone decode's; a "
            f"right transcript stays under {RATIO_WARN}): check that the transcript is the text of this "
            "recording (a typo, another take) and that this is the right audio file"
        )
    if left_out:
        reasons.append(
            f"{silent_speech:.0%} of the speech falls in the transcript's silences (a right transcript leaves "
            f"under {SILENT_SPEECH_WARN:.0%}): the transcript seems to miss words that were spoken; check that "
            "it covers the whole recording"
        )
    verdict: Verdict = "ok"
    if poor_fit or left_out:
        verdict = "mismatch" if cost_ratio > RATIO_GROSS or (poor_fit and left_out) else "suspect"
    return TranscriptCheck(verdict, cost_ratio, silent_speech, tuple(reasons))


def checked_alignment(
    samples: NDArray[np.float64], rate_hz: int, transcript: str, *, allow_mismatch: bool = False
) -> tuple[ForcedAlignment | None, TranscriptCheck]:
    """Forced alignment and its check. A gross mismatch raises :class:`TranscriptMismatchError` unless
    ``allow_mismatch``; then the alignment comes back with its check, or ``None`` when no path fitted."""
    try:
        alignment = force_align(samples, rate_hz, transcript)
    except TranscriptMismatchError as err:
        check = TranscriptCheck(
            "mismatch",
            math.nan,
            math.nan,
            (
                "no path through the transcript's words fits the audio: check that the transcript is the "
                "text of this recording and that this is the right audio file",
            ),
        )
        if not allow_mismatch:
            raise TranscriptMismatchError(str(err), check) from err
        return None, check
    check = check_alignment(alignment)
    if check.verdict == "mismatch" and not allow_mismatch:
        raise TranscriptMismatchError(f"cannot lip-sync: {check.message()}", check)
    return alignment, check
