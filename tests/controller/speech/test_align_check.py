"""The transcript check (speech/align_check.py) on real espeak-ng speech and real pocketsphinx: the right
transcript passes in several voices and speeds; another sentence, the words shuffled, or half the words
are flagged; `servoface lipsync` prints the warning, refuses a gross mismatch unless --allow-mismatch (and
says nothing about the right transcript: test_cli_speech)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray
from servoface.controller.cli import main
from servoface.controller.speech.align_check import (
    RATIO_GROSS,
    RATIO_WARN,
    SILENT_SPEECH_WARN,
    checked_alignment,
    verdict_of,
)
from servoface.controller.speech.audio import to_float, write_wav
from servoface.controller.speech.errors import TranscriptMismatchError
from servoface.controller.speech.espeak import synthesize
from servoface.controller.speech.lipsync import speech_from_recording

BOB = "Bob bought a big blue balloon for the baby."


@cache
def _recording(text: str, voice: str = "en-us", rate_wpm: int | None = None) -> tuple[NDArray[np.float64], int]:
    s = synthesize(text, voice=voice, rate_wpm=rate_wpm)
    return to_float(s.samples), s.sample_rate_hz


@pytest.mark.parametrize(
    ("text", "voice", "rate_wpm"),
    [
        (BOB, "en-us", None),
        ("Four hours of steady work faced us.", "en-us+f3", 130),
        ("The source of the huge river is the clear spring.", "en", 220),
    ],
)
def test_the_right_transcript_passes(text: str, voice: str, rate_wpm: int | None) -> None:
    samples, rate = _recording(text, voice, rate_wpm)
    alignment, check = checked_alignment(samples, rate, text)
    assert alignment is not None
    assert check.ok and check.reasons == (), check
    assert check.cost_ratio <= RATIO_WARN and check.silent_speech <= SILENT_SPEECH_WARN


def test_another_sentence_is_a_mismatch() -> None:
    samples, rate = _recording(BOB)
    with pytest.raises(TranscriptMismatchError, match="right audio file") as caught:
        checked_alignment(samples, rate, "The juice of lemons makes fine punch.")
    assert caught.value.check is not None and caught.value.check.verdict == "mismatch"


def test_shuffled_words_are_a_mismatch() -> None:
    samples, rate = _recording(BOB)
    alignment, check = checked_alignment(
        samples, rate, "balloon the baby bought Bob for a big blue", allow_mismatch=True
    )
    assert alignment is not None and check.verdict == "mismatch", check
    assert check.cost_ratio > RATIO_WARN


def test_half_the_words_is_a_warning_about_missing_words() -> None:
    samples, rate = _recording(BOB)
    alignment, check = checked_alignment(samples, rate, "Bob bought a big")
    assert alignment is not None and check.verdict == "suspect", check
    assert check.silent_speech > SILENT_SPEECH_WARN and "miss words" in check.message()


def test_allowing_a_mismatch_with_no_path_falls_back_to_the_envelope() -> None:
    speech = speech_from_recording(_recording(BOB), "The juice of lemons makes fine punch.", allow_mismatch=True)
    assert speech.method == "envelope" and speech.transcript_check is not None
    assert speech.transcript_check.verdict == "mismatch"
    assert speech.plan.duration_s > 1.0


@pytest.mark.parametrize(
    ("ratio", "silent", "verdict"),
    [
        (RATIO_WARN - 0.01, SILENT_SPEECH_WARN - 0.01, "ok"),
        (RATIO_WARN + 0.01, 0.0, "suspect"),
        (1.0, SILENT_SPEECH_WARN + 0.01, "suspect"),
        (RATIO_WARN + 0.01, SILENT_SPEECH_WARN + 0.01, "mismatch"),
        (RATIO_GROSS + 0.01, 0.0, "mismatch"),
    ],
)
def test_verdict_thresholds(ratio: float, silent: float, verdict: str) -> None:
    check = verdict_of(ratio, silent)
    assert check.verdict == verdict
    assert len(check.reasons) == (ratio > RATIO_WARN) + (silent > SILENT_SPEECH_WARN)


def _lipsync(tmp_path: Path, text: str, *extra: str) -> int:
    samples, rate = _recording(BOB)
    wav = write_wav(tmp_path / "take.wav", (samples * 32767).astype(np.int16), rate)
    return main(["lipsync", str(wav), "--text", text, "--out", str(tmp_path / "out"), "--no-video", *extra])


def test_cli_prints_the_warning_and_goes_ahead(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _lipsync(tmp_path, "Bob bought a big") == 0
    out, err = capsys.readouterr()
    assert out.startswith("aligned:") and (tmp_path / "out" / "speech.toml").exists()
    assert "warning: the transcript may not match the audio" in err and "covers the whole recording" in err


def test_cli_refuses_a_gross_mismatch_unless_allowed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    other = "The juice of lemons makes fine punch."
    assert _lipsync(tmp_path, other) == 2
    _, err = capsys.readouterr()
    assert "transcript" in err and "--allow-mismatch" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "speech.toml").exists()
    assert _lipsync(tmp_path, other, "--allow-mismatch") == 0
    out, err = capsys.readouterr()
    assert out.startswith("envelope:") and "warning: the transcript does not match the audio" in err
