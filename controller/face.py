"""`Face`: the ten-line Python API. Open a head on a port or on the emulator, set AUs or an expression,
play a script, look at a point, close safely.

    from servoface.controller.face import Face

    with Face.open("human", emulate=True) as face:      # or Face.open("my_head/", port="/dev/ttyUSB0")
        face.express("happiness", hold_s=1.0)
        face.set_aus({"AU1": 0.6, "AU2": 0.6}, transition_s=0.3)
        face.look_at((150.0, 40.0, 600.0))              # mm, head frame: +x the head's left, +y up, +z ahead
        face.play("controller/scripts/human_performance.toml")
    # leaving the block eases to neutral, turns torque off and closes the port

`Face` is a blocking convenience on top of the head service (:mod:`servoface.controller.service`): the
first motion starts ``face.service`` (its loop thread then owns the bus), every call submits one command on
the service's "face" track and waits for it (and for the servos to settle) before it returns; every frame
passes the twin gate. Other front ends may drive ``face.service`` at the same time (a tracker on the gaze
track, an e-stop from any thread). ``face.traces`` keeps the recent frame traces of the calls;
``with face.service.paused_loop():`` hands the bus to the caller for work on ``face.pipeline`` by hand.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import signal
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any

from servoface.calibration import HeadCalibration
from servoface.controller import stop_signals
from servoface.controller.alive.gaze import gaze_config_for, solve_look_at
from servoface.controller.alive.gaze_layer import angles_to_aus
from servoface.controller.errors import ControllerError
from servoface.controller.frame import FrameValidator
from servoface.controller.loop import LoopStats
from servoface.controller.performance import Performance, Samples
from servoface.controller.pipeline import FrameTrace, Pipeline
from servoface.controller.safe_stop import EASE_S, MAX_EASE_S, StopReport, safe_stop
from servoface.controller.script import Script, load_script
from servoface.controller.service import CommandHandle, HeadService, Status, head_calibration, open_head
from servoface.controller.service.commands import check_point_mm
from servoface.controller.service.observers import MAX_QUEUE
from servoface.controller.timeline_on_head import pose_refusal
from servoface.controller.trace_ring import TraceRing
from servoface.controller.values import as_finite, check_seconds, printable_repr
from servoface.hardware.bus import ServoBus
from servoface.hardware.driver import Driver, FastSyncRead
from servoface.hardware.errors import HardwareError
from servoface.hardware.fault_policy import FaultPolicy
from servoface.sim.head import Head
from servoface.sim.heads import load_head

__all__ = ["SETTLE_MAX_S", "Face", "head_calibration", "unknown_expression"]


def unknown_expression(name: Any, known: Any, head: Head) -> str:
    """``unknown expression 'x' (did you mean 'y'?); known: [...]`` for a name the head's library lacks; a
    built-in of the other kind of face is named as such (`Face.express` and the command line say it alike)."""
    from servoface.sim.expressions import load_library

    names = sorted(known)
    close = difflib.get_close_matches(name, names, n=1) if isinstance(name, str) else []
    maybe = f" (did you mean {close[0]!r}?)" if close else ""
    other = "dog" if head.face_type == "human" else "human"
    if not close and isinstance(name, str) and name in load_library(other):
        maybe = f" (a {other} expression; head {head.name!r} is a {head.face_type} face)"
    return f"unknown expression {printable_repr(name)}{maybe}; known: {names}"


_GAZE_AUS = frozenset({"AU51", "AU52", "AU53", "AU54", "AU55", "AU56", "AU61", "AU62", "AU63", "AU64"})
_DOG_GAZE_AUS = frozenset({"AU9", "AU10", "AU11", "AU12", "AU13"})
TRACK = "face"

SETTLE_MAX_S = 2.0  # longest a call keeps walking the servos to its final frame after its motion ends


class _Interrupt:
    """Ctrl-C during a blocking call: the first stops the call (the face holds where it is), a second
    raises KeyboardInterrupt as usual. Only in the main thread; the previous handler comes back after.

    Under installed `StopSignals` (the CLI: SIGINT, SIGTERM, SIGHUP) it installs nothing and defers to them:
    the signal stops the head service's loop, which goes down the one stop path by itself; the call only
    notices (``by_signals``) and returns."""

    def __init__(self) -> None:
        self._pressed = threading.Event()
        self.signals: stop_signals.StopSignals | None = None

    def is_set(self) -> bool:
        return self._pressed.is_set() or (self.signals is not None and self.signals.requested)

    @property
    def by_signals(self) -> bool:
        return self.signals is not None and self.signals.requested

    @contextmanager
    def armed(self) -> Iterator[_Interrupt]:
        installed = stop_signals.active()
        if installed is not None:
            self.signals = installed
            yield self
            return
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        previous = signal.getsignal(signal.SIGINT)

        def handler(signum: int, frame: Any) -> None:
            if self._pressed.is_set():
                raise KeyboardInterrupt
            self._pressed.set()

        signal.signal(signal.SIGINT, handler)
        try:
            yield self
        finally:
            signal.signal(signal.SIGINT, previous)


class _CallFrames:
    """The frames of one call, taken as they arrive: timed from the call's start (as the timeline it plays
    sees them: service time - start), the newest kept (`TraceRing`, and the face's own history `Face.traces`)
    and the loop statistics counted over every one. A call of hours holds a ring, not hours of frames (a
    frame trace is ~4 KB: ~0.75 GB an hour at 50 Hz when they were all kept until the call ended)."""

    def __init__(self, rate_hz: float, face_ring: deque[FrameTrace]) -> None:
        self.ring = TraceRing()
        self.face_ring = face_ring
        self.stats = LoopStats(rate_hz)
        self.period_s = 1.0 / rate_hz
        self.first_t_s: float | None = None
        self.last_t_s = 0.0

    def take(self, traces: Iterable[FrameTrace], started_s: float) -> None:
        """Add the frames of the call (those from ``started_s`` on, service time)."""
        stats = self.stats
        for trace in traces:
            if trace.t_s < started_s - 1e-9:
                continue
            trace = dataclasses.replace(trace, t_s=trace.t_s - started_s)
            stats.lateness_s.add(trace.late_s)
            stats.recent_lateness_s.append(trace.late_s)
            stats.callback_s.add(trace.timings_ms.get("total_ms", 0.0) / 1e3)
            if trace.late_s > self.period_s / 4:
                stats.late += 1
            stats.frames += 1
            if self.first_t_s is None:
                self.first_t_s = trace.t_s
            self.last_t_s = trace.t_s
            self.ring.append(trace)
            self.face_ring.append(trace)

    def finish(self, missed: int, overruns: int) -> LoopStats:
        """The call's loop statistics (``missed`` / ``overruns``: the loop's counts over the call)."""
        stats = self.stats
        stats.missed, stats.overruns = max(0, missed), max(0, overruns)
        if self.first_t_s is not None:
            stats.elapsed_s = self.last_t_s - self.first_t_s + self.period_s
        return stats


def _has_say_cues(script: Script) -> bool:
    from servoface.controller.script_say import say_cues

    return bool(say_cues(script))


class _Fixed:
    """A source played for a fixed length (what ``HeadService.play`` takes as a recording)."""

    def __init__(self, source: Samples, duration_s: float) -> None:
        self.source = source
        self.duration_s = duration_s
        self.face_type = getattr(source, "face_type", None)

    def sample(self, t_s: float) -> Any:
        return self.source.sample(t_s)


class Face:
    """A head driven through the whole pipeline by its head service. Build it with `Face.open`."""

    def __init__(
        self,
        head: Head,
        pipeline: Pipeline,
        *,
        driver: Driver | None = None,
        bus: ServoBus | None = None,
        chain: Any = None,
        history: int = 3000,
    ) -> None:
        self.head = head
        self.pipeline = pipeline
        self.driver = driver
        self.bus = bus
        self.chain = chain  # the emulated chain, when emulating
        self.validator = FrameValidator(head.face_type)
        self.pose: dict[str, float] = {}
        self.t_s = 0.0
        self.traces: deque[FrameTrace] = deque(maxlen=history)
        self._history = history
        self._service: HeadService | None = None
        self._closed = False
        self._library: Any = None  # the head's expression library, read once (express)
        self._gaze_config: Any = None  # the head's gaze geometry, read once (look_at)
        self.stop_report: StopReport | None = None

    @property
    def service(self) -> HeadService:
        """The head service that runs this face (started on first use; it then owns the bus)."""
        self._check_open()
        if self._service is None:
            self._service = HeadService(self.head, self.pipeline)
        return self._service

    # -- opening ------------------------------------------------------------------------------------
    @classmethod
    def open(
        cls,
        head: str | Path | Head = "human",
        *,
        port: str | None = None,
        baud: int = 1_000_000,
        emulate: bool = False,
        wire_time: bool = True,
        rate_hz: float = 50.0,
        calibration: HeadCalibration | str | Path | None = None,
        fast_sync_read: FastSyncRead = "auto",
        policy: FaultPolicy | None = None,
        position_sentinel: bool = True,
    ) -> Face:
        """Open ``head`` (built-in name, profile folder, or a loaded Head) on ``port`` or on the emulator.

        The servos are configured from the profile and calibration (EEPROM only with torque off, limits
        written as a hardware backstop), the gate's tables are built (a stop signal there ends the start-up
        with torque never on), torque goes on with goals pinned to present positions and the Bus Watchdog
        armed, and the pipeline starts from where the servos are. Any failure leaves every servo torque off.
        ``fast_sync_read``, ``policy`` and ``position_sentinel`` go to the `Driver` (``position_sentinel=False``:
        no Indirect Address written, positions read directly).
        """
        opened = open_head(
            head,
            port=port,
            baud=baud,
            emulate=emulate,
            wire_time=wire_time,
            rate_hz=rate_hz,
            calibration=calibration,
            fast_sync_read=fast_sync_read,
            policy=policy,
            position_sentinel=position_sentinel,
        )
        return cls(opened.head, opened.pipeline, driver=opened.driver, bus=opened.bus, chain=opened.chain)

    @classmethod
    def offline(
        cls,
        head: str | Path | Head = "human",
        *,
        rate_hz: float = 50.0,
        calibration: HeadCalibration | str | Path | None = None,
    ) -> Face:
        """The pipeline without a bus: muscle model, calibration and twin gate only (previews, checks)."""
        the_head = head if isinstance(head, Head) else load_head(head)
        return cls(the_head, Pipeline(the_head, head_calibration(the_head, calibration), rate_hz=rate_hz))

    # -- motion -------------------------------------------------------------------------------------
    def _perform(
        self,
        submit: Callable[[HeadService], CommandHandle],
        duration_s: float,
        *,
        track: str | tuple[str, ...] = TRACK,
    ) -> Performance:
        """Submit a command (on ``track``; or several, returning the one that ends last), wait for it and for
        the servos to settle; the call's frames and stats. Ctrl-C stops what plays on ``track`` where it is."""
        svc = self.service
        rate = svc.rate_hz
        # drained every 0.1 s below; sized for the whole call all the same (up to the cap) should the wait stall
        expected = (duration_s + SETTLE_MAX_S) * rate + 200
        sub = svc.subscribe("trace", maxlen=int(min(max(expected, 1000), MAX_QUEUE)))
        stats0 = svc.loop_stats
        missed0, overruns0 = stats0.missed, stats0.overruns
        interrupt = _Interrupt()
        frames = _CallFrames(rate, self.traces)
        try:
            with interrupt.armed():
                handle = submit(svc)  # a bad command raises here; nothing was queued
                while not handle.wait(0.1).final and not interrupt.is_set():
                    if handle.started_s is not None:  # the frames so far leave the queue (its memory)
                        frames.take(sub.drain(), handle.started_s)
                if interrupt.by_signals:  # the loop stops by itself (and goes down the stop path)
                    handle.wait(5.0)
                elif interrupt.is_set() and not handle.done():
                    for name in (track,) if isinstance(track, str) else track:
                        svc.stop(name, hold=True).wait(2.0)
                elif handle.status is Status.DONE:
                    last = svc.last_trace
                    svc.wait_settled(-1 if last is None else last.index - 1, timeout_s=SETTLE_MAX_S)
        finally:
            sub.close()
        started = handle.started_s if handle.started_s is not None else float("inf")
        frames.take(sub.drain(), started)  # the rest of the call's frames (a failed call's too: they went on the wire)
        if handle.status is Status.FAILED:
            raise handle.error if handle.error is not None else ControllerError(handle.detail)
        if svc.error is not None:
            raise svc.error
        stats1 = svc.loop_stats
        missed = stats1.missed - missed0 if stats1 is stats0 else stats1.missed
        overruns = stats1.overruns - overruns0 if stats1 is stats0 else stats1.overruns
        perf = Performance(frames.ring, frames.finish(missed, overruns), rate, interrupt.is_set())
        self.t_s += duration_s
        if frames.ring:  # the face track's pose (other front ends' tracks, e.g. a gaze, are theirs)
            mine = svc.status().tracks[TRACK].aus
            self.pose = {au: v for au, v in mine.items() if abs(v) > 1e-12}
        return perf

    def set_aus(self, aus: Mapping[str, float], *, transition_s: float = 0.4, hold_s: float = 0.0) -> Performance:
        """Move to the AU pose ``aus`` (AUs not named go to 0) over ``transition_s``, then hold."""
        if not isinstance(aus, Mapping):
            raise ControllerError(f"set_aus: aus must be a mapping of AU name -> intensity, got {type(aus).__name__}")
        pose = self.validator.pose(dict(aus), where="set_aus")
        transition = max(check_seconds(transition_s, "set_aus: transition_s"), 1.0 / self.pipeline.rate_hz)
        hold = check_seconds(hold_s, "set_aus: hold_s")
        return self._perform(
            lambda svc: svc.set_aus(pose, track=TRACK, transition_s=transition, hold_s=hold), transition + hold
        )

    def express(
        self, name: str, *, intensity: float = 1.0, transition_s: float = 0.5, hold_s: float = 1.0
    ) -> Performance:
        """Move to a named expression's apex (scaled by ``intensity``) and hold it."""
        library = self._expressions()
        if not isinstance(name, str) or name not in library:
            raise ControllerError(f"express: {unknown_expression(name, library, self.head)}")
        level = as_finite(intensity)
        if level is None or not 0 <= level <= 1:
            raise ControllerError(f"express: intensity must be a number within 0..1, got {printable_repr(intensity)}")
        check_seconds(transition_s, "express: transition_s")  # named as the caller wrote them
        check_seconds(hold_s, "express: hold_s")
        apex = {au: v * level for au, v in library[name].apex().items()}
        # what the head's own AU table, direct table or muscles refuse: named as an expression
        why = pose_refusal(
            self.pipeline.targets_for, apex, f"express: expression {name!r} at intensity {level:g}", self.head.name
        )
        if why is not None:
            raise ControllerError(why)
        return self.set_aus(apex, transition_s=transition_s, hold_s=hold_s)

    def _expressions(self) -> Any:
        """The head's expression library (read from its files on first use, then kept)."""
        if self._library is None:
            from servoface.sim.expressions import load_library

            self._library = load_library(self.head.expressions_path or self.head.face_type)
        return self._library

    def neutral(self, transition_s: float = 0.6) -> Performance:
        return self.set_aus({}, transition_s=transition_s)

    def look_at(self, point_mm: tuple[float, float, float], *, transition_s: float = 0.5) -> Performance:
        """Turn eyes and head towards a point (head frame, mm); eyes lead, the neck takes the rest."""
        point = check_point_mm(point_mm, field="look_at: point_mm")  # a ServiceError (a ControllerError)
        check_seconds(transition_s, "look_at: transition_s")
        if self._gaze_config is None:
            self._gaze_config = gaze_config_for(self.head.face_type, self.head)
        cfg = self._gaze_config
        gaze = solve_look_at(point, cfg)
        gaze_aus = angles_to_aus(
            self.head.face_type,
            cfg,
            gaze.head_yaw_deg,
            gaze.head_pitch_deg,
            gaze.eye_yaw_deg,
            gaze.eye_pitch_deg,
        )
        keep = _GAZE_AUS if self.head.face_type == "human" else _DOG_GAZE_AUS
        pose = {au: v for au, v in self.pose.items() if au not in keep}
        pose.update({au: v for au, v in gaze_aus.items() if abs(v) > 1e-9})
        return self.set_aus(pose, transition_s=transition_s)

    def play(self, script: Script | str | Path | Any, *, duration_s: float | None = None) -> Performance:
        """Play a timeline script to its end (or for ``duration_s`` at most): a TOML file, a shipped
        script by name (``"human_performance"``, see ``servoface list scripts``) or a loaded Script; or a
        recording (``servoface.controller.inputs.load_recording``) to its end. A script's ``say`` cues and its
        sound file (``[script] audio``) are spoken as `say` speaks (the speech track, the sound on the audio
        device, the mouth on its clock: `servoface.controller.speech.script_play`)."""
        loaded = (
            script if not isinstance(script, str | Path) else load_script(script, library=self.head.expressions_path)
        )
        end_s = getattr(loaded, "end_s", None)
        if end_s is None:
            end_s = getattr(loaded, "duration_s", None)
        if end_s is None or not callable(getattr(loaded, "sample", None)):
            raise ControllerError(
                f"play: expected a script (path, shipped name or Script) or a recording, got {script!r}"
            )
        if getattr(loaded, "face_type", self.head.face_type) != self.head.face_type:
            where = getattr(loaded, "source", "") or type(loaded).__name__
            raise ControllerError(
                f"script {where} is for a {loaded.face_type} face; head {self.head.name!r} is {self.head.face_type}"
            )
        end_s = float(end_s)
        if duration_s is not None:
            if (
                isinstance(duration_s, bool)
                or not isinstance(duration_s, int | float)
                or not (0 < duration_s < math.inf)
            ):
                raise ControllerError(f"play: duration_s must be a positive number of seconds, got {duration_s!r}")
            end_s = min(end_s, float(duration_s))
        if isinstance(loaded, Script) and (loaded.audio or _has_say_cues(loaded)):  # spoken as say() speaks
            from servoface.controller.speech.script_play import play_script_speaking

            return play_script_speaking(self, loaded, duration_s=duration_s).performance
        limit = end_s if end_s > 0 else None
        return self._perform(lambda svc: svc.play(loaded, track=TRACK, duration_s=limit), end_s)

    def perform(self, source: Samples, duration_s: float) -> Performance:
        """Play anything with ``sample(t_s) -> AUFrame`` (a Timeline, a Recording, a Script) from its time 0
        for exactly ``duration_s`` (a recording holds its last frame past its end)."""
        if isinstance(duration_s, bool) or not isinstance(duration_s, int | float) or not (0 <= duration_s < math.inf):
            raise ControllerError(f"perform: duration_s must be a finite number of seconds >= 0, got {duration_s!r}")
        if not callable(getattr(source, "sample", None)):
            raise ControllerError(f"perform: expected something with sample(t_s) -> AUFrame, got {source!r}")
        theirs = getattr(source, "face_type", self.head.face_type)
        if theirs != self.head.face_type:
            raise ControllerError(f"perform: the source is for a {theirs} face; head is {self.head.face_type}")
        length = float(duration_s)
        timeline = _Fixed(source, length)
        return self._perform(lambda svc: svc.play(timeline, track=TRACK, duration_s=length or None), length)

    def follow(
        self, source: Samples, duration_s: float | None = None, *, until: Callable[[], bool] | None = None
    ) -> Performance:
        """Follow a live source (``servoface.controller.inputs.StreamSource``) or a recording for ``duration_s``
        (None = until Ctrl-C, or until ``until()`` is true); the source's dropout policy decides what a gap
        in the data looks like."""
        self._check_open()
        if duration_s is not None and not (isinstance(duration_s, int | float) and 0 < duration_s < math.inf):
            raise ControllerError(
                f"follow: duration_s must be a positive number of seconds or None, got {duration_s!r}"
            )
        perf = self._perform(lambda svc: svc.follow(source, track=TRACK, duration_s=duration_s, until=until), 0.0)
        if perf.traces:
            self.t_s += perf.traces[-1].t_s - perf.traces[0].t_s
        return perf

    def say(self, text: str, *, voice: str = "en-us", out_dir: str | Path | None = None) -> Performance:
        """Speak ``text`` (espeak-ng) with lip sync through the head service's speech track
        (``HeadService.speak``): the mouth AUs are the speech track's, the rest of the face stays as it is;
        the sound on the default output when there is one (the mouth follows its clock). ``out_dir``: also
        write speech.wav/.toml."""
        from servoface.controller.speech.say import speak_text

        self._check_open()
        return speak_text(self, text, voice=voice, out_dir=out_dir)

    def hold(self, seconds: float) -> Performance:
        return self.set_aus(self.pose, transition_s=0.0, hold_s=seconds)

    # -- closing ------------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise ControllerError("this Face is closed")

    def close(
        self,
        *,
        ease_s: float = EASE_S,
        max_ease_s: float = MAX_EASE_S,
        hurry: Callable[[], bool] | None = None,
        reason: str = "end",
    ) -> StopReport | None:
        """The one stop path (`servoface.controller.safe_stop`): ease to neutral through the gate (at most
        ``max_ease_s``; not at all when ``ease_s`` is 0; once ``hurry()`` — or a second stop signal —
        turns true, straight to neutral at the gate's caps), torque off on every servo (retried, carrying
        on), Bus Watchdog disarmed, port (and emulator) closed. With a head service running, its shutdown
        does it on the loop thread.

        Returns the `StopReport` (also kept as ``face.stop_report``; None offline): ``report.unreached``
        names servos whose torque-off was not confirmed. Safe to call twice (the second call returns the
        first report)."""
        if self._closed:
            return self.stop_report
        if isinstance(ease_s, bool) or not isinstance(ease_s, int | float) or not math.isfinite(ease_s):
            ease_s = EASE_S  # a stop never refuses to stop
        ease = max(0.0, float(ease_s))
        if self._service is not None:  # no sound outlives the face that spoke it (a device plays on otherwise)
            from servoface.controller.speech.playback import stop_sounds

            stop_sounds(self._service)
        try:
            if self._service is not None:
                self.stop_report = self._service.shutdown(
                    ease_s=ease, max_ease_s=max_ease_s, reason=reason, hurry=hurry
                )
            elif self.driver is not None:  # no motion ever started the service: the caller owns the bus
                signals = stop_signals.active()
                self.stop_report = safe_stop(
                    self.pipeline,
                    self.driver,
                    from_aus=self.pose,
                    ease=ease > 0,
                    ease_s=ease,
                    max_ease_s=max_ease_s,
                    hurry=hurry or (lambda: signals is not None and signals.hurry),
                    reason=reason,
                )
            elif self.bus is not None:
                self.bus.close()
        finally:
            self._closed = True
            self.pose = {}
            if self.chain is not None:
                self.chain.close()
        return self.stop_report

    def __enter__(self) -> Face:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        signals = stop_signals.active()
        if signals is not None and signals.requested:
            reason = signals.name or "signal"
        elif exc is None:
            reason = "end"
        elif isinstance(exc, KeyboardInterrupt):
            reason = "interrupted"
        elif isinstance(exc, HardwareError):
            reason = "bus failure"
        else:
            reason = f"error: {type(exc).__name__}"
        self.close(reason=reason)
