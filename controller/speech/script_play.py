"""A script with ``say`` cues, played on a head: the script on the face track, each cue spoken through the
head service's speech slot exactly as `Face.say` speaks (one code path: :func:`~.say.schedule_speech`).

Each cue is synthesised by espeak-ng before anything moves (the sound and its phoneme events), then the
script (its say clips silent, :func:`~servoface.controller.script_say.without_say`) and every cue are
submitted with absolute start times on the service clock: the script from ``t0``, a cue at ``t0 + at_s``.
So the mouth is the speech track's while it talks (its AUs override the face track's), the sound goes to
the audio device for that time plus the pipeline's frame time (silent without a device: then the monotonic
clock is master, as for `servoface say`), and the jaw stays within its thermal budget, carried from one
cue to the next. The cues all go on the service's one ``speech`` track whatever script track they name (a
later cue takes over from an earlier one still talking, as on a script track)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from servoface.controller.au_names import head_au_names
from servoface.controller.errors import ControllerError
from servoface.controller.script_say import SayCue, say_cues, without_say
from servoface.controller.service.handles import Status
from servoface.controller.speech.say import (
    END_MARGIN_S,
    START_AHEAD_S,
    ScheduledSpeech,
    SpokenRun,
    pipeline_latency_s,
    schedule_speech,
)
from servoface.controller.speech.visemes import mouth_aus

if TYPE_CHECKING:
    from servoface.controller.face import Face
    from servoface.controller.performance import Performance
    from servoface.controller.script import Script
    from servoface.controller.speech.lipsync import Speech


@dataclass(frozen=True)
class SpokenScript:
    """A script played with its say cues spoken: the run's frames, and per cue spoken how it went."""

    performance: Performance
    cues: tuple[SayCue, ...]
    spoken: tuple[SpokenRun, ...]

    def lines(self) -> list[str]:
        """One line per cue for a terminal: when, what, where the sound went, which clock the mouth followed."""
        out = []
        for cue, run in zip(self.cues, self.spoken, strict=True):
            words = cue.text if len(cue.text) <= 40 else cue.text[:37] + "..."
            out.append(
                f"said {words!r} at {cue.at_s:g} s on the speech track: sound: {run.sound}; "
                f"the mouth followed the {run.clock} clock"
            )
        return out


def play_script_speaking(
    face: Face, script: Script, *, duration_s: float | None = None, audio_out: bool = True
) -> SpokenScript:
    """Play ``script`` on ``face`` (blocking) to its end, or for ``duration_s`` at most, its say cues spoken
    through ``HeadService.speak``. Synthesis errors raise before anything is submitted."""
    from servoface.controller.speech.lipsync import speech_from_text

    end_s = float(script.end_s) if duration_s is None else min(float(script.end_s), float(duration_s))
    cues = tuple(c for c in say_cues(script) if c.at_s < end_s)
    speeches = [speech_from_text(c.text, voice=c.voice) for c in cues]  # before anything moves
    cut_s = math.inf if duration_s is None else end_s  # --duration cuts a cue (mouth and sound) there
    total_s = max(
        [end_s, *(min(c.at_s + _length_s(s), cut_s) for c, s in zip(cues, speeches, strict=True))]
    )  # the face track holds the script's last pose until the last cue has finished
    muted = dataclasses.replace(without_say(script), end_s=total_s)
    allowed = head_au_names(face.head) & mouth_aus(face.head.face_type)
    latency_s = pipeline_latency_s(face)
    scheduled: list[ScheduledSpeech] = []
    handles: list[Any] = []

    def submit(service: Any) -> Any:
        t0 = service.now_s() + START_AHEAD_S
        script_handle = service.play(muted, track="face", at_s=t0, duration_s=total_s if total_s > 0 else None)
        handles.append(script_handle)
        for cue, speech in zip(cues, speeches, strict=True):
            base = {au: v for au, v in muted.sample(cue.at_s).aus.items() if au in allowed}
            one = schedule_speech(
                face,
                speech,
                t0 + cue.at_s,
                base=base,
                latency_s=latency_s,
                audio_out=audio_out,
                length_s=None if duration_s is None else cut_s - cue.at_s,
            )
            scheduled.append(one)
            handles.append(one.handle)
        return script_handle  # it ends last (or with the last cue): the run's frames are timed from its start

    perf = face._perform(submit, total_s, track=("face", "speech"))  # noqa: SLF001 - the Face's own runner
    for handle in handles:  # (the one waited for raised in _perform already)
        if handle.status is Status.FAILED:
            raise handle.error if handle.error is not None else ControllerError(f"play: {handle.detail}")
    return SpokenScript(perf, cues, tuple(one.finish(perf) for one in scheduled))


def _length_s(speech: Speech) -> float:
    """How long an utterance holds the speech track (as `schedule_speech` plays it)."""
    return max(speech.plan.duration_s, speech.plan.audio_end_s) + END_MARGIN_S
