"""The script format's speech cue: ``[[play]] at_s = 1.0, say = "Hello there"`` (+ ``voice = "en-us"``).

**Track.** A say cue is always on the script's ``speech`` track (``track`` may be left out or be
``"speech"``; any other name is refused naming ``play[i].track``): a head has one mouth and its service one
speech track, so a cue on another script track could not be played as written — two cues on two tracks
would overlap in the script but not on the head, where a later utterance takes over from an earlier one
still talking. On the one track the script shows what the head does: a later cue cuts an earlier one,
in the studio's scrubbing, in previews and on the head alike.

The text is synthesised by espeak-ng (:mod:`servoface.controller.speech`, offline) into the same lip-sync
clip `servoface say` plays: the mouth AUs as per-AU keys, visemes from espeak's own phoneme events,
providing nothing after the utterance. While a script has a speech cue, the mouth AUs the speech drives
blend ``override`` (speech owns the mouth while it talks, as on the head service's speech track) unless the
script's ``[blend] rules`` name them. Plans are cached per (text, voice, face, allowed AUs): scrubbing a
script in the studio re-parses it often.

The clip is a :class:`SayClip`: the lip-sync clip plus the words and voice it was made from, so a front end
that drives a head can find the cues (:func:`say_cues`) and speak them through the head service's speech
slot instead — real synthesis, the sound on the audio device, the mouth on the audio clock, within the
jaw's budget (:mod:`servoface.controller.speech.script_play`; `Face.play` and `servoface play` do) — while
the rest of the script plays from :func:`without_say` (the same timeline, the say clips silent). Sampled
as it is (the studio's scrubbing, previews), the script shows the same mouth on its own clock, without
sound."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from servoface.controller.script import Script
    from servoface.controller.timeline import Timeline

SAY_TRACK = "speech"  # the only script track a say cue may be on (the head service's speech track)
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


def say_clip(text: str, voice: str, face_type: str, allowed: frozenset[str] | None, name: str) -> SayClip:
    """The lip-sync clip of ``text`` (raises the speech package's errors when espeak-ng cannot say it)."""
    return SayClip(_plan(text, voice).clip(face_type, allowed, name=name), text, voice)


def say_problem(err: Exception) -> tuple[str, str]:
    """(field, message) for a cue espeak-ng could not say: ``voice`` when the voice is what it refused."""
    text = str(err)
    field = "voice" if text.startswith("voice") else "say"
    return field, f"cannot synthesise it ({type(err).__name__}: {text})"


@dataclass(frozen=True)
class SayClip:
    """A say cue's lip-sync clip (a timeline clip: it provides the mouth AUs while it runs, nothing after),
    with the words and voice it was synthesised from."""

    inner: Any  # the lip-sync ChannelClip
    text: str
    voice: str

    @property
    def name(self) -> str:
        return str(self.inner.name)

    @property
    def holds(self) -> bool:
        return bool(self.inner.holds)

    @property
    def duration_s(self) -> float:
        return float(self.inner.duration_s)

    def sample(self, t_s: float, from_pose: Mapping[str, float]) -> dict[str, float]:
        return dict(self.inner.sample(t_s, from_pose))

    def end_pose(self, from_pose: Mapping[str, float]) -> dict[str, float]:
        return dict(self.inner.end_pose(from_pose))

    def targets(self) -> Iterator[tuple[str, float]]:
        return iter(self.inner.targets())


@dataclass(frozen=True)
class _Spoken:
    """Where a say clip was: as long, providing nothing (the head service's speech track speaks it)."""

    duration_s: float
    name: str = "say (spoken on the speech track)"
    holds: bool = False

    def sample(self, t_s: float, from_pose: Mapping[str, float]) -> dict[str, float]:
        return {}

    def end_pose(self, from_pose: Mapping[str, float]) -> dict[str, float]:
        return {}

    def targets(self) -> Iterator[tuple[str, float]]:
        return iter(())


@dataclass(frozen=True)
class SayCue:
    """One ``say`` entry of a script: when (script time), on which script track, what and in which voice."""

    at_s: float
    track: str
    text: str
    voice: str
    duration_s: float  # the lip-sync clip's length in the script


def say_cues(script: Script) -> list[SayCue]:
    """The script's say cues, in time order."""
    from servoface.controller.timeline.track import Track

    timeline = script.timeline
    cues = []
    for name in timeline.layer_names:
        layer = timeline.layer(name)
        if isinstance(layer, Track):
            for placed in layer.items:
                if isinstance(placed.clip, SayClip):
                    clip = placed.clip
                    cues.append(SayCue(placed.start_s, name, clip.text, clip.voice, clip.duration_s))
    return sorted(cues, key=lambda c: c.at_s)


def without_say(script: Script, *, tracks: frozenset[str] = frozenset()) -> Script:
    """The script with every say clip silent (same length, providing nothing) — and every clip of ``tracks``:
    what plays on the face track while the head service's speech track speaks. The other layers are shared,
    not copied."""
    from servoface.controller.timeline import Timeline
    from servoface.controller.timeline.track import Track

    old = script.timeline
    new: Timeline = Timeline(old.face_type, blend=old.blend)
    new.validator = old.validator  # the head's allowed AUs, as the script was built with
    for name in old.layer_names:
        layer = old.layer(name)
        mute_all = name in tracks
        if isinstance(layer, Track) and any(mute_all or isinstance(p.clip, SayClip) for p in layer.items):
            track = Track(name, layer.initial_pose)
            for p in layer.items:
                clip = _Spoken(p.clip.duration_s) if mute_all or isinstance(p.clip, SayClip) else p.clip
                track.add(p.start_s, clip, p.from_pose)
            layer = track
        new.add_layer(name, layer)
    return dataclasses.replace(script, timeline=new)


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
