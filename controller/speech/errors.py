"""Errors of the speech package."""

from __future__ import annotations

from servoface.controller.errors import ControllerError


class SpeechError(ControllerError):
    """Speech input or synthesis failed; the message names the field, file or voice and what was expected."""


class SynthesisUnavailableError(SpeechError):
    """No espeak-ng library could be loaded (install hint in the message)."""


class AlignmentError(SpeechError):
    """Forced alignment could not align the audio with its transcript."""
