"""The script format's speech cue: ``[[play]] at_s = 1.0, say = "Hello there"`` (+ ``voice = "en-us"``,
``track`` default ``"speech"``). The text is synthesised by espeak-ng (:mod:`servoface.controller.speech`,
offline) into the same lip-sync clip `servoface say` plays: the mouth AUs as per-AU keys, visemes from
espeak's own phoneme events, providing nothing after the utterance. While a script has a speech cue, the
mouth AUs the speech drives blend ``override`` (speech owns the mouth while it talks, as on the head
service's speech track) unless the script's ``[blend] rules`` name them. Plans are cached per
(text, voice, face, allowed AUs): scrubbing a script in the studio re-parses it often.

The sound itself is not part of the script's timeline: `servoface say` plays and writes it; a script that
should also sound names a file with ``[script] audio``."""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from typing import Any

MAX_SAY_CHARS = 2000
VOICE_CHARS = frozenset("abcdefghijklmnopqrstuvwxyz0123456789-+_")


def check_say(text: Any, voice: Any) -> str | None:
    """None when ``text``/``voice`` are usable, else what is wrong (the caller names the field)."""
    if not isinstance(text, str) or not text.strip():
        return f"say: expected the words to speak (a non-empty string), got {text!r:.60}"
    if len(text) > MAX_SAY_CHARS:
        return f"say: at most {MAX_SAY_CHARS} characters, got {len(text)}"
    if not all(c.isprintable() for c in text):
        return "say: expected printable text (no control characters)"
    if not isinstance(voice, str) or not 1 <= len(voice) <= 40 or not set(voice.lower()) <= VOICE_CHARS:
        return f"voice: expected an espeak-ng voice name like 'en-us', got {voice!r:.60}"
    return None


@lru_cache(maxsize=64)
def _plan(text: str, voice: str) -> Any:
    from servoface.controller.speech.lipsync import speech_from_text

    return speech_from_text(text, voice=voice).plan


def say_clip(text: str, voice: str, face_type: str, allowed: frozenset[str] | None, name: str) -> Any:
    """The lip-sync clip of ``text`` (raises the speech package's errors when espeak-ng cannot say it)."""
    return _plan(text, voice).clip(face_type, allowed, name=name)


def with_say_rules(blend: Mapping[str, Any], plays: Any, face_type: str) -> dict[str, Any]:
    """``blend`` (the script's [blend] table) with the mouth AUs ``override`` when a play entry says
    something and the rules do not already name them."""
    from servoface.controller.speech.visemes import mouth_aus

    out = dict(blend)
    if not isinstance(plays, list) or not any(isinstance(p, Mapping) and "say" in p for p in plays):
        return out
    rules = out.get("rules", {})
    if not isinstance(rules, Mapping):
        return out  # the script's own error is reported by the blend parser
    out["rules"] = {**{au: "override" for au in sorted(mouth_aus(face_type))}, **rules}
    return out
