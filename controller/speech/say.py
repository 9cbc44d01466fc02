"""Speech on a head: the speech track takes the mouth AUs while the face track keeps the rest.

**Blend rule** (documented in the README): while speech plays, the mouth AUs of the face's speech recipe
(human: AU10, AU18, AU19, AU20, AU22, AU24, AU25, AU26; dog: AU1, AU2, AU7) are the speech track's
(``override``); every other AU — brows, lids, eyes, cheeks, smile corners (AU12, AU6), head — stays the
face track's, so an expression held while talking keeps its brows and lids, and a smile talks smiling.
When the speech clip ends it provides nothing and the face track has the mouth again.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from servoface.controller.au_names import head_au_names
from servoface.controller.speech.lipsync import Speech
from servoface.controller.speech.visemes import mouth_aus
from servoface.controller.timeline import BlendPolicy, BlendRule, Timeline

if TYPE_CHECKING:
    from servoface.controller.face import Face
    from servoface.controller.performance import Performance


def speech_timeline(face_type: str, speech: Speech, base_pose: dict[str, float], allowed: frozenset[str]) -> Timeline:
    """A timeline: the face track holds ``base_pose``; the speech track plays the lip sync over it."""
    clip = speech.plan.clip(face_type, allowed & mouth_aus(face_type))
    rules = {au: BlendRule.OVERRIDE for au in mouth_aus(face_type) if au in allowed}
    timeline = Timeline(face_type, allowed=allowed, blend=BlendPolicy(rules=rules), initial_pose=base_pose)  # type: ignore[arg-type]
    timeline.track("face")
    timeline.play(clip, 0.0, track="speech")
    return timeline


@dataclass(frozen=True)
class SpokenRun:
    """What a spoken run did: its frames, and on the monotonic clock when the mouth clock's 0 was (the
    first frame's due time) and when the sound started (or would have: no device). The sound starts
    ``audio_start_s`` (the lead) plus ``latency_s`` (the pipeline's frame time) after the mouth clock."""

    performance: Performance
    start_monotonic_s: float
    audio_start_monotonic_s: float
    latency_s: float
    sound: str  # where the sound went, or why it did not play


def say_on_face(face: Face, speech: Speech, *, audio_out: bool = True) -> SpokenRun:
    """Play ``speech`` on an open face (blocking), the mouth on the speech track over the face's pose; the
    sound (when a device exists) starts ``plan.audio_start_s`` after the first frame."""
    from servoface.controller.speech.playback import open_audio_out

    allowed = head_au_names(face.head)
    timeline = speech_timeline(face.head.face_type, speech, dict(face.pose), allowed)
    out = open_audio_out() if audio_out else None
    duration = max(speech.plan.duration_s, speech.plan.audio_end_s) + 0.15
    pose_before = dict(face.pose)
    latency_s = pipeline_latency_s(face)
    start = time.monotonic()
    audio_start = start + speech.plan.audio_start_s + latency_s
    if out is not None and out.available:
        out.play_at(speech.samples, speech.rate_hz, audio_start)
    perf = face._run(timeline, duration)  # noqa: SLF001 - the Face's own runner (bounded, traced, interruptible)
    face.pose = pose_before  # the expression is still held; the mouth is back at the face track's
    if out is not None:
        out.wait()
    sound = "not asked for" if out is None else out.reason
    return SpokenRun(perf, start, audio_start, latency_s, sound)


def pipeline_latency_s(face: Face) -> float:
    """How long a frame takes from its due time to its goals on the wire, from the face's recent frames
    (median of the last 25 frame times; 0 before any): the sound is delayed by this much so it meets
    the mouth on the wire, not in the pipeline."""
    import itertools
    import statistics

    recent = [t.timings_ms.get("total_ms", 0.0) for t in itertools.islice(reversed(face.traces), 25)]
    return statistics.median(recent) / 1e3 if recent else 0.0


def speak_text(face: Face, text: str, *, voice: str = "en-us", out_dir: str | Path | None = None) -> Performance:
    """``face.say(text)``: synthesise, plan and play; with ``out_dir``, also write speech.wav/speech.toml."""
    from servoface.controller.speech.lipsync import speech_from_text

    speech = speech_from_text(text, voice=voice)
    if out_dir is not None:
        write_outputs(speech, face.head.face_type, Path(out_dir), allowed=head_au_names(face.head))
    return say_on_face(face, speech).performance


def write_outputs(
    speech: Speech, face_type: str, out_dir: Path, *, allowed: frozenset[str] | None = None
) -> tuple[Path, Path]:
    """speech.wav + speech.toml (playable with ``servoface play``) in ``out_dir``."""
    import numpy as np
    from servoface.controller.speech.audio import write_wav
    from servoface.controller.speech.script_out import script_text, write_script

    wav = write_wav(out_dir / "speech.wav", (np.clip(speech.samples, -1, 1) * 32767).astype(np.int16), speech.rate_hz)
    title = speech.text or f"lip sync ({speech.method})"
    script = write_script(
        out_dir / "speech.toml", script_text(speech.plan, face_type, title=title, audio=wav.name, allowed=allowed)
    )
    return wav, script
