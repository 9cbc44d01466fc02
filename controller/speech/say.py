"""Speech on a head: the speech track takes the mouth AUs while the face track keeps the rest.

**Blend rule** (documented in the README): while speech plays, the mouth AUs of the face's speech recipe
(human: AU10, AU18, AU19, AU20, AU22, AU24, AU25, AU26; dog: AU1, AU2, AU7) are the speech track's
(``override``); every other AU — brows, lids, eyes, cheeks, smile corners (AU12, AU6), head — stays the
face track's, so an expression held while talking keeps its brows and lids, and a smile talks smiling.
When the speech clip ends it provides nothing and the face track has the mouth again.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoface.controller.au_names import head_au_names
from servoface.controller.speech.jaw_budget import BudgetReport, JawBudget, JawThermal, jaw_thermal
from servoface.controller.speech.lipsync import Speech
from servoface.controller.speech.visemes import mouth_aus

if TYPE_CHECKING:
    from servoface.controller.face import Face
    from servoface.controller.performance import Performance
    from servoface.controller.speech.playback import AudioClock, AudioClockedClip, AudioOut


START_AHEAD_S = 0.1  # the speech is scheduled this far ahead, so its start (and the sound's) is known exactly
END_MARGIN_S = 0.15  # the run covers the audio's end plus this (the mouth is at rest by then)


@dataclass(frozen=True)
class SpokenRun:
    """What a spoken run did: its frames; on the monotonic clock when the mouth clock's 0 was (the speech
    track's start) and when the sound started (or would have: no device); the clock the mouth followed
    (``"device"`` or ``"monotonic"``) and how far it moved the mouth from its schedule; the jaw budget."""

    performance: Performance
    start_monotonic_s: float
    audio_start_monotonic_s: float
    latency_s: float
    sound: str  # where the sound went, or why it did not play
    clock: str = "monotonic"
    shifts_s: tuple[float, ...] = ()  # per frame: mouth time - service time (0 on the monotonic clock)
    budget: BudgetReport | None = None


_BUDGETS: weakref.WeakKeyDictionary[Any, JawBudget] = weakref.WeakKeyDictionary()


def jaw_budget_for(service: Any) -> JawBudget:
    """The jaw account of a head service (one per head, kept across utterances)."""
    budget = _BUDGETS.get(service)
    if budget is None:
        driver = getattr(service, "driver", None)
        budget = JawBudget(policy=getattr(driver, "policy", None))
        _BUDGETS[service] = budget
    return budget


def say_on_face(face: Face, speech: Speech, *, audio_out: bool = True, budget: JawBudget | None = None) -> SpokenRun:
    """Play ``speech`` on an open face (blocking) through ``HeadService.speak``: the mouth clip on the speech
    track (its AUs override the face track's while it plays), timed by the audio clock (the device's when
    a sound device plays it, else the monotonic clock), with the jaw's opening within its thermal budget
    (``budget``, default: the head's own account)."""
    svc = face.service
    allowed = head_au_names(face.head) & mouth_aus(face.head.face_type)
    latency_s = pipeline_latency_s(face)
    at_s = svc.now_s() + START_AHEAD_S
    under = svc.status().tracks.get("face")  # the face's own mouth (an expression held): crossfaded
    base = {au: v for au, v in (under.aus if under is not None else {}).items() if au in allowed}
    scheduled: list[ScheduledSpeech] = []

    def submit(service: Any) -> Any:
        scheduled.append(
            schedule_speech(svc, speech, at_s, base=base, latency_s=latency_s, audio_out=audio_out, budget=budget)
        )
        return scheduled[0].handle

    duration = max(speech.plan.duration_s, speech.plan.audio_end_s) + END_MARGIN_S
    perf = face._perform(submit, duration, track="speech")  # noqa: SLF001 - the Face's own runner
    return scheduled[0].finish(perf)


@dataclass
class ScheduledSpeech:
    """One utterance submitted to the speech slot: its command, the clock its mouth follows, its sound."""

    handle: Any  # the speech track's CommandHandle
    timed: AudioClockedClip
    clock: AudioClock
    out: AudioOut | None
    start_monotonic_s: float
    audio_start_monotonic_s: float
    latency_s: float
    end_s: float  # on the service clock: when its command ends
    budget: BudgetReport | None

    def finish(self, performance: Performance) -> SpokenRun:
        """Wait for the sound to finish and say how the run went."""
        if self.out is not None:
            self.out.wait()
        sound = "not asked for" if self.out is None else self.out.reason
        return SpokenRun(
            performance,
            self.start_monotonic_s,
            self.audio_start_monotonic_s,
            self.latency_s,
            sound,
            self.clock.name,
            tuple(self.timed.shifts),
            self.budget,
        )


def schedule_speech(
    service: Any,
    speech: Speech,
    at_s: float,
    *,
    base: Mapping[str, float],
    latency_s: float,
    audio_out: bool = True,
    budget: JawBudget | None = None,
    length_s: float | None = None,
) -> ScheduledSpeech:
    """Submit ``speech`` to a head service's speech slot from ``at_s`` (service time, ahead of now) without
    waiting (every front end's speech comes here: `Face.say`, a script's say cues, the node's ``cmd/say``):
    the plan within the jaw's budget, the clip crossfaded from and back to ``base`` (the face's own
    mouth there), the sound started on the audio device for the mouth's time plus ``latency_s`` (silent
    without one: then the monotonic clock is master), the clip timed by that clock. ``length_s`` cuts the
    utterance (mouth and sound) that long after ``at_s``."""
    from servoface.controller.speech.playback import AudioClockedClip, MonotonicAudioClock, open_audio_out

    svc = service
    face_type = svc.head.face_type
    allowed = head_au_names(svc.head) & mouth_aus(face_type)
    start = svc.clock.to_monotonic_s(at_s)
    account = budget if budget is not None else jaw_budget_for(svc)
    plan, report = account.apply(speech.plan, start, jaw_state(svc))
    clip = plan.clip(face_type, allowed, base=dict(base))
    audio_start = start + plan.audio_start_s + latency_s
    duration = max(plan.duration_s, plan.audio_end_s) + END_MARGIN_S
    samples = speech.samples
    if length_s is not None and length_s < duration:
        duration = max(0.0, float(length_s))
        keep = int(max(0.0, start + duration - audio_start) * speech.rate_hz)
        samples = samples[:keep]
    out = open_audio_out(svc) if audio_out and len(samples) else None
    clock: AudioClock = (
        out.play_at(samples, speech.rate_hz, audio_start) if out is not None else MonotonicAudioClock(audio_start)
    )
    timed = AudioClockedClip(clip, clock, start, latency_s, plan.audio_start_s, duration)
    handle = svc.speak(timed, at_s=at_s)
    if out is not None:
        out.stop_with(handle)  # a stop, an e-stop or a newer utterance ends the sound with the mouth
    return ScheduledSpeech(handle, timed, clock, out, start, audio_start, latency_s, at_s + duration, report)


def jaw_state(service: Any) -> JawThermal | None:
    """The head's jaw as its driver last read it (None: no jaw, offline, not read yet)."""
    jaw_id = service.head.servo_ids.get("jaw")
    return jaw_thermal(service, jaw_id) if jaw_id is not None else None


def budgeted_mouth(service: Any, clip: Any, start_monotonic_s: float) -> tuple[Any, BudgetReport]:
    """A mouth clip that is not a plan (a script's edited speech keys) within the head's jaw budget, from
    ``start_monotonic_s``: the same account and driver state as every utterance."""
    from servoface.controller.speech.jaw_clip import budget_clip

    return budget_clip(clip, service.head.face_type, start_monotonic_s, jaw_budget_for(service), jaw_state(service))


def service_latency_s(service: Any) -> float:
    """The last frame's time from due to wire (0 before any): :func:`pipeline_latency_s` for a front end
    that keeps no frames of its own (the studio, the node)."""
    last = service.last_trace
    return 0.0 if last is None else float(last.timings_ms.get("total_ms", 0.0)) / 1e3


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
