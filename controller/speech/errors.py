"""Errors of the speech package."""

from __future__ import annotations

from typing import TYPE_CHECKING

from servoface.controller.errors import ControllerError

if TYPE_CHECKING:
    from servoface.controller.speech.align_check import TranscriptCheck


class SpeechError(ControllerError):
    """Speech input or synthesis failed; the message names the field, file or voice and what was expected."""


class SynthesisUnavailableError(SpeechError):
    """No espeak-ng library could be loaded (install hint in the message)."""


class AlignmentError(SpeechError):
    """Forced alignment could not align the audio with its transcript."""


class TranscriptMismatchError(AlignmentError):
    """The transcript is grossly not the text of the audio (no alignment path, or a far worse fit than a
    free phone decode); ``check`` is the transcript check when there was one."""

    def __init__(self, message: str, check: TranscriptCheck | None = None) -> None:
        super().__init__(message)
        self.check = check
