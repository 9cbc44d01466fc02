"""Recorded speech + its transcript -> phonemes with times: forced alignment with pocketsphinx 5.

pocketsphinx's wheel ships its US-English acoustic model and the CMU dictionary (``pocketsphinx/model``),
so nothing is downloaded. Alignment runs two passes: word alignment of the transcript, then phone
alignment (``set_alignment`` / ``get_alignment``), at 100 frames/s (10 ms); a boundary the decoder
reports at frame ``k`` is placed between the acoustic centres of frames ``k-1`` and ``k`` (``k * 10 ms``
plus half the 25.6 ms window less half a frame: +7.8 ms), where the change it detected lies. Words not in the dictionary
are spelled out from espeak-ng's phonemes of that word (ARPAbet-mapped) when espeak-ng is present, else
refused with a message naming them.

The aligner always finds *some* timing when it finds a path at all, so a wrong transcript (a typo, the
wrong audio file) would otherwise go unnoticed: ``speech/align_check.py`` checks that the transcript fits
the audio (a goodness-of-pronunciation test against a free phone loop, and speech left in silence), and
when no path through the transcript fits the audio at all this module raises ``TranscriptMismatchError``.
"""

from __future__ import annotations

import re
import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.audio import resample
from servoface.controller.speech.errors import AlignmentError, SpeechError, TranscriptMismatchError

ALIGN_RATE_HZ = 16000
FRAME_S = 0.01
WINDOW_S = 0.025625  # pocketsphinx's analysis window (its default -wlen; the bundled model's feat.params keep it)
DECODER_LOCK = threading.Lock()

#: espeak-ng English mnemonics -> ARPAbet, for words missing from the CMU dictionary
_ESPEAK_TO_ARPABET = {
    "p": "P",
    "b": "B",
    "m": "M",
    "f": "F",
    "v": "V",
    "T": "TH",
    "D": "DH",
    "t": "T",
    "d": "D",
    "k": "K",
    "g": "G",
    "N": "NG",
    "h": "HH",
    "tS": "CH",
    "dZ": "JH",
    "S": "SH",
    "Z": "ZH",
    "s": "S",
    "z": "Z",
    "n": "N",
    "l": "L",
    "r": "R",
    "j": "Y",
    "w": "W",
    "3:": "ER",
    "3": "ER",
    "a": "AE",
    "A:": "AA",
    "aI": "AY",
    "aU": "AW",
    "V": "AH",
    "@": "AH",
    "e": "EH",
    "E": "EH",
    "eI": "EY",
    "i": "IY",
    "i:": "IY",
    "I": "IH",
    "0": "AA",
    "O:": "AO",
    "O": "AO",
    "oU": "OW",
    "OI": "OY",
    "u:": "UW",
    "U": "UH",
    "e@": "EH",
    "i@": "IY",
    "U@": "UH",
    "A@": "AA",
    "O@": "AO",
    "@L": "L",
    "a#": "AE",
    "I#": "IH",
}


@dataclass(frozen=True)
class AlignedPhone:
    """An ARPAbet phone (``SIL`` for silence) from ``start_s`` to ``end_s`` in the audio, with its word."""

    phone: str
    start_s: float
    end_s: float
    word: str


@dataclass(frozen=True)
class DecodedPhone:
    """A phone as the decoder aligned it: from frame ``start_frame`` (10 ms frames) for ``n_frames``, with its
    acoustic score (pocketsphinx's integer log units, higher is better)."""

    phone: str
    word: str
    start_frame: int
    n_frames: int
    score: int


@dataclass(frozen=True)
class ForcedAlignment:
    """A forced alignment: the phones in seconds, the same phones in frames with their scores, the number
    of frames decoded, and the 16 kHz 16-bit PCM that was aligned (the transcript check decodes it again)."""

    phones: tuple[AlignedPhone, ...]
    decoded: tuple[DecodedPhone, ...]
    n_frames: int
    pcm: bytes


def normalise_transcript(text: str) -> list[str]:
    """Lower-case words of letters and apostrophes (numbers and punctuation dropped), as the dictionary has."""
    if not isinstance(text, str) or not text.strip():
        raise SpeechError(f"transcript: expected a non-empty text, got {text!r:.60}")
    words = re.findall(r"[a-z']+", text.lower())
    words = [w.strip("'") for w in words if w.strip("'")]
    if not words:
        raise SpeechError(f"transcript: no words found in {text[:60]!r}")
    return words


def make_decoder() -> object:
    """A pocketsphinx decoder (US English, 16 kHz, wide beams); use it while holding ``DECODER_LOCK``."""
    try:
        import pocketsphinx
    except ImportError as err:
        raise SpeechError("forced alignment needs pocketsphinx: pip install 'pocketsphinx>=5'") from err
    # wide beams: alignment has one path to follow; the default beams lose it on synthetic or noisy speech
    # (with beams of 1e-100, 3 of 22 corpus sentences found no path; these found all)
    return pocketsphinx.Decoder(
        samprate=ALIGN_RATE_HZ,
        bestpath=False,
        loglevel="FATAL",
        beam=1e-200,
        pbeam=1e-200,
        wbeam=1e-200,
        lpbeam=1e-200,
        lponlybeam=1e-200,
        fwdflat=False,
        maxhmmpf=-1,
    )


def _spell_missing(decoder: object, words: list[str]) -> None:
    missing = [w for w in dict.fromkeys(words) if decoder.lookup_word(w) is None]  # type: ignore[attr-defined]
    if not missing:
        return
    try:
        from servoface.controller.speech.espeak import synthesize
    except SpeechError:
        raise AlignmentError(f"transcript: words not in the dictionary: {missing}") from None
    for word in missing:
        phones = []
        for p in synthesize(word).phonemes:
            name = p.phoneme.replace("'", "").replace(",", "")
            if name.startswith("_"):
                continue
            arpa = _ESPEAK_TO_ARPABET.get(name) or _ESPEAK_TO_ARPABET.get(name[:1])
            if arpa:
                phones.append(arpa)
        if not phones:
            raise AlignmentError(f"transcript: cannot spell {word!r} (not in the dictionary)")
        decoder.add_word(word, " ".join(phones), True)  # type: ignore[attr-defined]


def pcm_for_alignment(samples: NDArray[np.float64], rate_hz: int) -> bytes:
    """Mono audio (-1..1 at ``rate_hz``) as the decoder takes it: 16 kHz, 16-bit little-endian PCM."""
    x = resample(np.asarray(samples, dtype=np.float64), int(rate_hz), ALIGN_RATE_HZ)
    if len(x) < ALIGN_RATE_HZ * 0.1:
        raise SpeechError("audio: expected at least 0.1 s of speech to align")
    return bytes((np.clip(x, -1.0, 1.0) * 32767.0).astype("<i2").tobytes())


def align(samples: NDArray[np.float64], rate_hz: int, transcript: str) -> list[AlignedPhone]:
    """Forced alignment of mono audio (-1..1 at ``rate_hz``) with its transcript: phones with times."""
    return list(force_align(samples, rate_hz, transcript).phones)


def force_align(samples: NDArray[np.float64], rate_hz: int, transcript: str) -> ForcedAlignment:
    """:func:`align`, keeping the decoder's frames and scores (for the transcript check)."""
    words = normalise_transcript(transcript)
    pcm = pcm_for_alignment(samples, rate_hz)
    with DECODER_LOCK:
        decoder = make_decoder()
        _spell_missing(decoder, words)
        try:
            decoder.set_align_text(" ".join(words))  # type: ignore[attr-defined]
            for second_pass in (False, True):
                if second_pass:
                    decoder.set_alignment()  # type: ignore[attr-defined]
                decoder.start_utt()  # type: ignore[attr-defined]
                decoder.process_raw(pcm, full_utt=True)  # type: ignore[attr-defined]
                decoder.end_utt()  # type: ignore[attr-defined]
            alignment = decoder.get_alignment()  # type: ignore[attr-defined]
            n_frames = int(decoder.n_frames())  # type: ignore[attr-defined]
        except RuntimeError as err:
            # the first pass found no path through the transcript's words (pocketsphinx: "Failed to set up
            # sub-word alignment"): with the wide beams above, this is a transcript that is not this audio's
            raise TranscriptMismatchError(
                "cannot align the audio with its transcript: no path through the transcript's words fits "
                f"the audio ({err}); check that the transcript is the text of this recording and that this "
                "is the right audio file"
            ) from err
    if alignment is None:
        raise AlignmentError("cannot align the audio with its transcript (no alignment found)")
    # a boundary at frame k lies between the acoustic centres of frames k-1 and k (each frame's window
    # starts at k * FRAME_S and is WINDOW_S long): k * FRAME_S + (WINDOW_S - FRAME_S) / 2, not k * FRAME_S
    centre = (WINDOW_S - FRAME_S) / 2
    end_s = len(pcm) / 2 / ALIGN_RATE_HZ
    out = []
    decoded = []
    for word in alignment:
        for phone in word:
            start = min(phone.start * FRAME_S + (centre if phone.start > 0 else 0.0), end_s)
            stop = min((phone.start + phone.duration) * FRAME_S + centre, end_s)
            out.append(AlignedPhone(phone.name, start, max(stop, start), word.name))
            decoded.append(DecodedPhone(phone.name, word.name, phone.start, phone.duration, phone.score))
    if not out:
        raise AlignmentError("alignment is empty: is the transcript the text of this audio?")
    return ForcedAlignment(tuple(out), tuple(decoded), n_frames, pcm)
