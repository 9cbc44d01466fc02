"""A script that speaks, played on a head: the script on the face track, its speech through the head
service's speech slot exactly as `Face.say` speaks (one code path: :func:`~.say.schedule_speech`).

Two kinds of speech in a script:

- **say cues** (``[[play]] say = "..."``): each is synthesised by espeak-ng before anything moves (sound and
  phoneme events, :func:`prepare`), then spoken on the speech track at the script's start + its ``at_s``:
  the mouth is the speech track's while it talks (its AUs override the face track's), the sound goes to the
  audio device for that time plus the pipeline's frame time (silent without a device: then the monotonic
  clock is master, as for `servoface say`), the jaw stays within its thermal budget, carried from one cue
  to the next. A cue is always on the script's ``speech`` track (the parser refuses another ``track``) and
  speaks on the service's one speech track (a later cue takes over from an earlier one still talking, as
  on the script track).
- **a sound file** (``[script] audio = "speech.wav"`` + ``audio_start_s``, what `servoface say --out` and
  `lipsync` write): read before anything moves, played from the script's start + ``audio_start_s``; the
  script's ``speech`` track (the mouth keys written with it) plays on the service's speech track slaved to
  that sound's clock, as a say cue's mouth is, its jaw within the same thermal budget
  (:mod:`.jaw_clip`: the keys' jaw opening scaled down as a plan's would be; the lips as written).

Every front end plays a speaking script here: `Face.play` / `servoface play` (:func:`play_script_speaking`,
blocking), the studio and the network node (:func:`submit_script_speaking`, returning the script's
command). A stop of the script's or the speech's command (Ctrl-C, e-stop, shutdown) stops its sound.

The rest of the script (:func:`~servoface.controller.script_say.without_say`: the same timeline, the speech
silent) plays on the face track from ``t0``; everything is submitted with absolute start times."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from servoface.controller.au_names import head_au_names
from servoface.controller.errors import ControllerError
from servoface.controller.script_say import SayCue, say_cues, without_say
from servoface.controller.service.handles import Status
from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.jaw_budget import BudgetReport
from servoface.controller.speech.say import (
    END_MARGIN_S,
    START_AHEAD_S,
    ScheduledSpeech,
    SpokenRun,
    budgeted_mouth,
    pipeline_latency_s,
    schedule_speech,
    service_latency_s,
)
from servoface.controller.speech.visemes import mouth_aus

if TYPE_CHECKING:
    from servoface.controller.face import Face
    from servoface.controller.performance import Performance
    from servoface.controller.script import Script
    from servoface.controller.service.handles import CommandHandle
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


def prepare(script: Script, *, audio_dir: Path | None = None) -> Prepared:
    """Synthesise every say cue and read the script's sound file (SpeechError naming the cue or the file):
    the CLI calls this before the port is opened, so a cue espeak-ng cannot say moves nothing. The sound
    file is beside the script, or in ``audio_dir`` (the studio's scripts folder: its scripts are text)."""
    from servoface.controller.speech.audio import read_wav
    from servoface.controller.speech.lipsync import speech_from_text

    cues = tuple(say_cues(script))
    if cues and script.audio and _edited_mouth(script):
        raise SpeechError(
            f"{script.source}: script.audio: the speech track has both say cues and mouth keys for the sound file "
            f"{script.audio!r}; a head has one speech track, so the keys could not follow the sound (nor the "
            "jaw budget) while the cues speak: move the say cues to a script of their own, or remove "
            "[script] audio and the keys"
        )
    speeches = []
    for cue in cues:
        try:
            speeches.append(speech_from_text(cue.text, voice=cue.voice))
        except SpeechError as err:
            raise SpeechError(f"{script.source}: say cue at {cue.at_s:g} s: {err}") from err
    audio = None
    path = script.audio_path if audio_dir is None or not script.audio else Path(audio_dir) / script.audio
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
    budget: BudgetReport | None = None  # what the jaw budget did to that mouth


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
                f"the mouth followed the {run.clock} clock{budget_note(run.budget)}"
            )
        if self.audio is not None:
            a = self.audio
            mouth = f"the {SPEECH_TRACK} track's mouth followed the {a.clock} clock" if a.mouth else "no mouth keys"
            out.append(f"played {a.name} at {a.start_s:g} s: sound: {a.sound}; {mouth}{budget_note(a.budget)}")
        return out


def budget_note(report: BudgetReport | None) -> str:
    """``"; jaw budget: ..."`` when the budget changed the jaw (a warm jaw, a long talk), else nothing."""
    if report is None or (report.level == 0 and report.min_scale >= 1.0):
        return ""
    return (
        f"; jaw budget: thermal level {report.level}, the jaw x{report.jaw_gain * report.min_scale:.2f} at least, "
        f"scaled down on {report.scaled_share:.0%} of it"
    )


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


def _edited_mouth(script: Script) -> bool:
    """True when the script's speech track has clips that are not say cues (mouth keys, as `say --out` writes)."""
    from servoface.controller.script_say import SayClip
    from servoface.controller.timeline.track import Track

    if SPEECH_TRACK not in script.timeline.layer_names:
        return False
    layer = script.timeline.layer(SPEECH_TRACK)
    return isinstance(layer, Track) and any(not isinstance(p.clip, SayClip) for p in layer.items)


def _speech_track(script: Script, cues: tuple[SayCue, ...]) -> Any:
    """The script's speech track when its mouth goes with the sound file (not when say cues are on it:
    they take the service's speech track when they speak)."""
    from servoface.controller.timeline.track import Track

    if SPEECH_TRACK not in script.timeline.layer_names or cues:
        return None
    layer = script.timeline.layer(SPEECH_TRACK)
    return layer if isinstance(layer, Track) and layer.items else None


class SpeakingScript:
    """A speaking script made ready for one head service (no waiting, any front end): :meth:`submit` puts
    the muted script on ``track`` and every cue and the sound file's mouth on the speech track, each
    through the head's jaw budget, and returns the script's command (it ends last: the face track holds
    the script's last pose until the speech has finished, ``total_s``). `Face.play` waits for it; the
    studio and the network node return it."""

    def __init__(
        self,
        service: Any,
        script: Script,
        prepared: Prepared,
        *,
        duration_s: float | None = None,
        audio_out: bool = True,
        latency_s: float = 0.0,
        track: str = "face",
    ) -> None:
        self.service = service
        self.script = script
        self.latency_s = float(latency_s)
        self.audio_out = audio_out
        self.track = track
        self.duration_s = duration_s
        end_s = float(script.end_s) if duration_s is None else min(float(script.end_s), float(duration_s))
        self.cut_s = math.inf if duration_s is None else end_s  # --duration cuts the speech (mouth and sound)
        self.kept = [(c, s) for c, s in zip(prepared.cues, prepared.speeches, strict=True) if c.at_s < end_s]
        self.cues = tuple(c for c, _ in self.kept)
        ends = [min(c.at_s + _length_s(s), self.cut_s) for c, s in self.kept]
        audio = prepared.audio
        self.sound = audio if audio is not None and script.audio_start_s < end_s else None
        if self.sound is not None:
            ends.append(min(script.audio_start_s + len(self.sound[0]) / self.sound[1] + END_MARGIN_S, self.cut_s))
        self.mouth_track = _speech_track(script, self.cues) if self.sound is not None else None
        self.total_s = max([end_s, *ends])  # the face track holds the last pose until the speech has finished
        muted = without_say(script, tracks=frozenset({SPEECH_TRACK}) if self.mouth_track is not None else frozenset())
        self.muted = dataclasses.replace(muted, end_s=self.total_s)
        self.scheduled: list[ScheduledSpeech] = []
        self.handles: list[Any] = []
        self.played: list[tuple[AudioOut | None, str]] = []
        self.budgets: list[BudgetReport] = []  # the sound file's mouth's (a cue's is on its ScheduledSpeech)

    def submit(self, at_s: float | None = None) -> CommandHandle:
        """Submit everything from ``at_s`` (service time; default: START_AHEAD_S from now); the script's
        command handle."""
        svc, script = self.service, self.script
        allowed = head_au_names(svc.head) & mouth_aus(svc.head.face_type)
        t0 = svc.now_s() + START_AHEAD_S if at_s is None else float(at_s)
        total = self.total_s
        script_handle: CommandHandle = svc.play(
            self.muted, track=self.track, at_s=t0, duration_s=total if total > 0 else None
        )
        self.handles.append(script_handle)
        for cue, speech in self.kept:
            base = {au: v for au, v in self.muted.sample(cue.at_s).aus.items() if au in allowed}
            length = None if self.duration_s is None else self.cut_s - cue.at_s
            one = schedule_speech(
                svc,
                speech,
                t0 + cue.at_s,
                base=base,
                latency_s=self.latency_s,
                audio_out=self.audio_out,
                length_s=length,
            )
            self.scheduled.append(one)
            self.handles.append(one.handle)
        if self.sound is not None:
            out, clock = _play_sound(
                svc, self.sound, t0, script.audio_start_s, self.latency_s, self.cut_s, self.audio_out
            )
            if out is not None:
                out.stop_with(script_handle)  # the script stopped (Ctrl-C, e-stop, shutdown): its sound too
            self.played.append((out, clock.name))
            if self.mouth_track is not None:
                from servoface.controller.speech.playback import AudioClockedClip

                start = svc.clock.to_monotonic_s(t0)
                mouth, report = budgeted_mouth(svc, _TrackClip(self.mouth_track), start)
                self.budgets.append(report)
                length = min(mouth.duration_s, self.cut_s)
                timed = AudioClockedClip(mouth, clock, start, self.latency_s, script.audio_start_s, length)
                handle = svc.speak(timed, at_s=t0)
                if out is not None:
                    out.stop_with(handle)
                self.handles.append(handle)
        return script_handle

    def check(self) -> None:
        """Raise the error of any of its commands that failed."""
        for handle in self.handles:
            if handle.status is Status.FAILED:
                raise handle.error if handle.error is not None else ControllerError(f"play: {handle.detail}")

    def finish(self, performance: Performance) -> SpokenScript:
        """Wait for the sounds to end; how it went."""
        self.check()
        audio = None
        script = self.script
        if self.played:
            out, clock_name = self.played[0]
            if out is not None:
                out.wait()
            where = "not asked for" if out is None else out.reason
            name = script.audio_path.name if script.audio_path is not None else script.audio
            budget = self.budgets[0] if self.budgets else None
            audio = SpokenAudio(name, script.audio_start_s, where, clock_name, self.mouth_track is not None, budget)
        return SpokenScript(performance, self.cues, tuple(one.finish(performance) for one in self.scheduled), audio)


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
    run = SpeakingScript(
        face.service, script, ready, duration_s=duration_s, audio_out=audio_out, latency_s=pipeline_latency_s(face)
    )
    perf = face._perform(lambda svc: run.submit(), run.total_s, track=("face", "speech"))  # noqa: SLF001
    return run.finish(perf)


def submit_script_speaking(
    service: Any,
    script: Script,
    *,
    track: str = "face",
    at_s: float | None = None,
    audio_dir: Path | None = None,
    audio_out: bool = True,
) -> tuple[CommandHandle, SpeakingScript]:
    """For a front end holding only a head service (the studio, the network node): synthesise, then submit
    ``script`` with its speech on ``service`` without waiting; (the script's command, the run). The sound
    goes to this machine's default output (the head's speaker), silent without one."""
    ready = prepare(script, audio_dir=audio_dir)
    run = SpeakingScript(service, script, ready, latency_s=service_latency_s(service), track=track, audio_out=audio_out)
    return run.submit(at_s), run


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
    out = open_audio_out(service) if audio_out and len(samples) else None
    clock = out.play_at(samples, rate, at) if out is not None else MonotonicAudioClock(at)
    return out, clock


def _length_s(speech: Speech) -> float:
    """How long an utterance holds the speech track (as `schedule_speech` plays it)."""
    return max(speech.plan.duration_s, speech.plan.audio_end_s) + END_MARGIN_S
