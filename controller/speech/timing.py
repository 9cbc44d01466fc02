"""Timed visemes: what every phoneme source (synthesis events, forced alignment) reduces to."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.visemes import VISEMES, viseme_of


@dataclass(frozen=True)
class TimedViseme:
    """A viseme held from ``start_s`` to ``end_s`` in the audio's clock, with the phonemes it came from."""

    viseme: str
    start_s: float
    end_s: float
    phonemes: tuple[str, ...] = ()

    @property
    def centre_s(self) -> float:
        return 0.5 * (self.start_s + self.end_s)

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s


def visemes_from_phonemes(
    phonemes: Sequence[tuple[str, float]], end_s: float, *, alphabet: str = "espeak"
) -> list[TimedViseme]:
    """(phoneme, start time) in time order, plus the end of the audio -> merged viseme segments (a run of
    phonemes with one viseme is one segment, so "mm" or "s z" is one mouth shape)."""
    out: list[TimedViseme] = []
    items = sorted(((str(p), float(t)) for p, t in phonemes), key=lambda pt: pt[1])
    for i, (phoneme, start) in enumerate(items):
        stop = items[i + 1][1] if i + 1 < len(items) else max(end_s, start)
        if not (start == start and stop == stop) or start < 0:  # NaN or negative
            raise SpeechError(f"phoneme {i} ({phoneme!r}): start time must be a finite time >= 0, got {start}")
        v = viseme_of(phoneme, alphabet)
        if stop <= start:
            continue
        if out and out[-1].viseme == v and abs(out[-1].end_s - start) < 1e-6:
            last = out[-1]
            out[-1] = TimedViseme(v, last.start_s, stop, (*last.phonemes, phoneme))
        else:
            out.append(TimedViseme(v, start, stop, (phoneme,)))
    for seg in out:
        if seg.viseme not in VISEMES:
            raise SpeechError(f"viseme {seg.viseme!r} is not one of {VISEMES}")
    return out


def onsets(segments: Sequence[TimedViseme]) -> list[tuple[str, float]]:
    """(viseme, onset) of every non-silent segment."""
    return [(s.viseme, s.start_s) for s in segments if s.viseme != "sil"]
