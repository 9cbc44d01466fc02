"""A script that speaks, played on a head: the script on the face track, its speech through the head
service's speech slot exactly as `Face.say` speaks (one code path: :func:`~.say.schedule_speech`).

Two kinds of speech in a script:

- **say cues** (``[[play]] say = "..."``): each is synthesised by espeak-ng before anything moves (sound and
  phoneme events, :func:`prepare`), then spoken on the speech track at the script's start + its ``at_s``:
  the mouth is the speech track's while it talks (its AUs override the face track's), the sound goes to the
  audio device for that time plus the pipeline's frame time (silent without a device: then the monotonic
  clock is master, as for `servoface say`), the jaw stays within its thermal budget, carried from one cue
  to the next. All cues go on the service's one ``speech`` track whatever script track they name (a later
  cue takes over from an earlier one still talking, as on a script track).
- **a sound file** (``[script] audio = "speech.wav"`` + ``audio_start_s``, what `servoface say --out` and
  `lipsync` write): read before anything moves, played from the script's start + ``audio_start_s``; the
  script's ``speech`` track (the mouth keys written with it) plays on the service's speech track slaved to
  that sound's clock, as a say cue's mouth is (the keys as written: no jaw budget on edited keys).

The rest of the script (:func:`~servoface.controller.script_say.without_say`: the same timeline, the speech
silent) plays on the face track from ``t0``; everything is submitted with absolute start times."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from servoface.controller.au_names import head_au_names
from servoface.controller.errors import ControllerError
from servoface.controller.script_say import SayCue, say_cues, without_say
from servoface.controller.service.handles import Status
from servoface.controller.speech.errors import SpeechError
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
    from servoface.controller.speech.playback import AudioOut

SPEECH_TRACK = "speech"  # the script track a sound file's mouth keys are on (as `say --out` writes them)


def speaks(script: Script) -> bool:
    """True when ``script`` has say cues or a sound file: played by :func:`play_script_speaking`."""
    return bool(say_cues(script)) or bool(script.audio)


@dataclass(frozen=True)
class Prepared:
    """What a speaking script needs before anything moves: each cue's synthesis, the sound file's samples."""

    cues: tuple[SayCue, ...]
    speeches: tuple[Speech, ...]
    audio: tuple[NDArray[np.float64], int] | None  # (mono samples -1..1, rate) of [script] audio


def prepare(script: Script) -> Prepared:
    """Synthesise every say cue and read the script's sound file (SpeechError naming the cue or the file):
    the CLI calls this before the port is opened, so a cue espeak-ng cannot say moves nothing."""
    from servoface.controller.speech.audio import read_wav
    from servoface.controller.speech.lipsync import speech_from_text

    cues = tuple(say_cues(script))
    speeches = []
    for cue in cues:
        try:
            speeches.append(speech_from_text(cue.text, voice=cue.voice))
        except SpeechError as err:
            raise SpeechError(f"{script.source}: say cue at {cue.at_s:g} s: {err}") from err
    audio = None
    path = script.audio_path
    if path is not None:
        try:
            audio = read_wav(path)
        except SpeechError as err:
            raise SpeechError(f"{script.source}: script.audio: {err}") from err
    return Prepared(cues, tuple(speeches), audio)


@dataclass(frozen=True)
class SpokenAudio:
    """How the script's sound file went: where the sound went, the clock the mouth followed."""

    name: str
    start_s: float  # script time
    sound: str
    clock: str
    mouth: bool  # the script's speech track followed it


@dataclass(frozen=True)
class SpokenScript:
    """A script played with its speech: the run's frames, per cue spoken how it went, the sound file's."""

    performance: Performance
    cues: tuple[SayCue, ...]
    spoken: tuple[SpokenRun, ...]
    audio: SpokenAudio | None = None

    def lines(self) -> list[str]:
        """One line per cue (and the sound file) for a terminal: when, what, where the sound went, which
        clock the mouth followed."""
        out = []
        for cue, run in zip(self.cues, self.spoken, strict=True):
            words = cue.text if len(cue.text) <= 40 else cue.text[:37] + "..."
            out.append(
                f"said {words!r} at {cue.at_s:g} s on the speech track: sound: {run.sound}; "
                f"the mouth followed the {run.clock} clock"
            )
        if self.audio is not None:
            a = self.audio
            mouth = f"the {SPEECH_TRACK} track's mouth followed the {a.clock} clock" if a.mouth else "no mouth keys"
            out.append(f"played {a.name} at {a.start_s:g} s: sound: {a.sound}; {mouth}")
        return out


class _TrackClip:
    """A script track as one clip for the service's speech track (provides nothing past its end)."""

    name = SPEECH_TRACK
    holds = False

    def __init__(self, track: Any) -> None:
        self.track = track
        self.duration_s = float(track.end_s)

    def sample(self, t_s: float, from_pose: Mapping[str, float]) -> dict[str, float]:
        return dict(self.track.sample(t_s)) if t_s < self.duration_s else {}

    def end_pose(self, from_pose: Mapping[str, float]) -> dict[str, float]:
        return {}

    def targets(self) -> Iterator[tuple[str, float]]:
        for placed in self.track.items:
            yield from placed.clip.targets()


def _speech_track(script: Script, cues: tuple[SayCue, ...]) -> Any:
    """The script's speech track when its mouth goes with the sound file (not when say cues are on it)."""
    from servoface.controller.timeline.track import Track

    if SPEECH_TRACK not in script.timeline.layer_names or any(c.track == SPEECH_TRACK for c in cues):
        return None
    layer = script.timeline.layer(SPEECH_TRACK)
    return layer if isinstance(layer, Track) and layer.items else None


def play_script_speaking(
    face: Face,
    script: Script,
    *,
    duration_s: float | None = None,
    audio_out: bool = True,
    prepared: Prepared | None = None,
) -> SpokenScript:
    """Play ``script`` on ``face`` (blocking) to its end, or for ``duration_s`` at most, its say cues and its
    sound file spoken through ``HeadService.speak`` (``prepared``: from :func:`prepare`, else made here)."""
    ready = prepared if prepared is not None else prepare(script)
    end_s = float(script.end_s) if duration_s is None else min(float(script.end_s), float(duration_s))
    cut_s = math.inf if duration_s is None else end_s  # --duration cuts the speech (mouth and sound) there
    kept = [(c, s) for c, s in zip(ready.cues, ready.speeches, strict=True) if c.at_s < end_s]
    cues = tuple(c for c, _ in kept)
    ends = [min(c.at_s + _length_s(s), cut_s) for c, s in kept]
    sound = ready.audio if ready.audio is not None and script.audio_start_s < end_s else None
    if sound is not None:
        ends.append(min(script.audio_start_s + len(sound[0]) / sound[1] + END_MARGIN_S, cut_s))
    track = _speech_track(script, cues) if sound is not None else None
    total_s = max([end_s, *ends])  # the face track holds the script's last pose until the speech has finished
    muted = without_say(script, tracks=frozenset({SPEECH_TRACK}) if track is not None else frozenset())
    muted = dataclasses.replace(muted, end_s=total_s)
    allowed = head_au_names(face.head) & mouth_aus(face.head.face_type)
    latency_s = pipeline_latency_s(face)
    scheduled: list[ScheduledSpeech] = []
    handles: list[Any] = []
    played: list[tuple[AudioOut | None, str]] = []

    def submit(service: Any) -> Any:
        t0 = service.now_s() + START_AHEAD_S
        script_handle = service.play(muted, track="face", at_s=t0, duration_s=total_s if total_s > 0 else None)
        handles.append(script_handle)
        for cue, speech in kept:
            base = {au: v for au, v in muted.sample(cue.at_s).aus.items() if au in allowed}
            length = None if duration_s is None else cut_s - cue.at_s
            one = schedule_speech(
                face, speech, t0 + cue.at_s, base=base, latency_s=latency_s, audio_out=audio_out, length_s=length
            )
            scheduled.append(one)
            handles.append(one.handle)
        if sound is not None:
            out, clock = _play_sound(service, sound, t0, script.audio_start_s, latency_s, cut_s, audio_out)
            played.append((out, clock.name))
            if track is not None:
                from servoface.controller.speech.playback import AudioClockedClip

                start = service.clock.to_monotonic_s(t0)
                mouth = _TrackClip(track)
                length = min(mouth.duration_s, cut_s)
                timed = AudioClockedClip(mouth, clock, start, latency_s, script.audio_start_s, length)
                handles.append(service.speak(timed, at_s=t0))
        return script_handle  # it ends last (or with the last speech): the run's frames are timed from its start

    perf = face._perform(submit, total_s, track=("face", "speech"))  # noqa: SLF001 - the Face's own runner
    for handle in handles:  # (the one waited for raised in _perform already)
        if handle.status is Status.FAILED:
            raise handle.error if handle.error is not None else ControllerError(f"play: {handle.detail}")
    audio = None
    if played:
        out, clock_name = played[0]
        if out is not None:
            out.wait()
        where = "not asked for" if out is None else out.reason
        name = script.audio_path.name if script.audio_path is not None else script.audio
        audio = SpokenAudio(name, script.audio_start_s, where, clock_name, track is not None)
    return SpokenScript(perf, cues, tuple(one.finish(perf) for one in scheduled), audio)


def _play_sound(
    service: Any,
    sound: tuple[NDArray[np.float64], int],
    t0: float,
    start_s: float,
    latency_s: float,
    cut_s: float,
    audio_out: bool,
) -> tuple[AudioOut | None, Any]:
    """Start the script's sound at script time ``start_s`` (+ the frame time) on the device, or on the
    monotonic clock without one; (the output, the clock the mouth follows)."""
    from servoface.controller.speech.playback import MonotonicAudioClock, open_audio_out

    samples, rate = sound
    if math.isfinite(cut_s):
        samples = samples[: int(max(0.0, cut_s - start_s) * rate)]
    at = service.clock.to_monotonic_s(t0) + start_s + latency_s
    out = open_audio_out() if audio_out and len(samples) else None
    clock = out.play_at(samples, rate, at) if out is not None else MonotonicAudioClock(at)
    return out, clock


def _length_s(speech: Speech) -> float:
    """How long an utterance holds the speech track (as `schedule_speech` plays it)."""
    return max(speech.plan.duration_s, speech.plan.audio_end_s) + END_MARGIN_S
