"""`HeadService`: one runtime owns a head; every front end drives it with commands.

The service owns the :class:`~servoface.controller.pipeline.Pipeline`, its driver and the one fixed-rate
loop thread that talks to the bus. Each frame the loop (1) applies an e-stop at once if one was asked for,
(2) applies the commands submitted since the last frame, in order, (3) starts the sources whose start time
has come, (4) samples every track and mixes them per AU (:mod:`.tracks`), (5) runs the mix through the
pipeline (muscle model -> calibration -> twin gate -> one Sync Write), (6) completes the commands whose
motion finished, and (7) offers the frame, telemetry, faults and status changes to the observers.

Commands are methods callable from any thread. Each is validated in the caller's thread (a bad one raises
:class:`~servoface.controller.errors.ControllerError` at once and changes nothing) and returns a
:class:`~servoface.controller.service.handles.CommandHandle`. Times (``at_s``) are on the service clock
(:meth:`now_s`). See the README section "The head service" for tracks, priorities and front ends.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any

from servoface.controller import stop_signals
from servoface.controller.errors import ControllerError
from servoface.controller.frame import FrameValidator
from servoface.controller.loop import FixedRateLoop, LoopStats, Tick
from servoface.controller.pipeline import FrameTrace, Pipeline
from servoface.controller.safe_stop import EASE_S, MAX_EASE_S, StopReport, bus_problem, safe_stop
from servoface.controller.service.clock import ServiceClock, check_duration_s, check_time_s
from servoface.controller.service.commands import (
    check_point_mm,
    check_then,
    expression_apex,
    play_source,
    pose_source,
)
from servoface.controller.service.errors import EStopLatchedError, ServiceClosedError, ServiceError
from servoface.controller.service.handles import CommandHandle, Status
from servoface.controller.service.observers import FrameSummary, ObserverHub, ServiceEvent, Subscription
from servoface.controller.service.slots import Slot, TrackTable, TrackView
from servoface.controller.service.sources import (
    AliveSource,
    ClipSource,
    FollowSource,
    GazeSource,
    Source,
    transition_clip,
)
from servoface.controller.service.tracks import DEFAULT_TRACKS, Mixer, TrackSpec
from servoface.controller.timeline.blend import BlendRule
from servoface.controller.timeline_on_head import pose_refusal
from servoface.hardware.driver import Driver
from servoface.hardware.errors import BusDisconnectedError, HardwareError
from servoface.hardware.snapshot import ChainSnapshot
from servoface.sim.errors import SimError
from servoface.sim.head import Head

ALIVE_TRACKS = frozenset({"blink", "idle"})
TORQUE_RETRIES = 3  # torque-off commands (and e-stops) retry a failed pass this many times
STOP_TIMEOUT_S = 30.0  # shutdown waits this long for the loop's stop (easing <= MAX_EASE_S, then torque off)

__all__ = ["HeadService", "ServiceStatus", "StopReport"]  # StopReport: servoface.controller.safe_stop's


@dataclass(frozen=True)
class ServiceStatus:
    """The service at a glance (after the last frame)."""

    t_s: float
    running: bool
    estop_latched: bool
    torque_on: bool
    frames: int
    late: int
    missed: int
    tracks: dict[str, TrackView]
    error: str = ""


class HeadService:
    """Owns ``pipeline`` (and its driver) and runs the loop thread. Build one with :meth:`open` or from
    parts; ``start=False`` leaves the thread to :meth:`start`. The driver is handed over to the loop thread,
    so after ``start`` only the service touches the bus.

    However the loop ends — :meth:`shutdown`, a stop signal under installed
    :class:`~servoface.controller.stop_signals.StopSignals` (checked every frame), a bus failure or the port
    failing (``stop_on_port_failure``), a crash — it ends in the one stop path on the loop thread, and
    ``service.report`` says how it went."""

    def __init__(
        self,
        head: Head,
        pipeline: Pipeline,
        *,
        tracks: Sequence[TrackSpec] = DEFAULT_TRACKS,
        priority: Sequence[str] | None = None,
        rules: Mapping[str, BlendRule | str] | None = None,
        validator: FrameValidator | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] | None = None,
        torque_on: bool | None = None,
        start: bool = True,
        name: str = "servoface-head",
        stop_on_port_failure: bool = True,
    ) -> None:
        self.head = head
        self.pipeline = pipeline
        self.stop_on_port_failure = stop_on_port_failure  # the port failed: stop (safe stop), never drive blind
        self.driver: Driver | None = pipeline.driver
        self.rate_hz = float(pipeline.rate_hz)
        self.period_s = 1.0 / self.rate_hz
        self.validator = validator or FrameValidator(head.face_type)
        self.mixer = Mixer(head.face_type, tracks, priority, rules)
        self.tracks = TrackTable(self.mixer)
        self.clock = ServiceClock(clock)
        self.observers = ObserverHub()
        self._lock = threading.Lock()
        self._inbox: deque[tuple[CommandHandle, Callable[[float], None]]] = deque()
        self._wake = threading.Event()
        self._estop_requested = threading.Event()
        self._estop_handle: CommandHandle | None = None  # the latest press
        self._estop_pending: deque[CommandHandle] = deque()  # presses the loop has not answered yet
        self._latched = False
        self._torque_on = self.driver is not None if torque_on is None else bool(torque_on)
        self._torque_wanted = self._torque_on
        self._closing = False
        self._stop_requested = False
        self._stop_reason: str | None = None  # why the loop stopped ("end", "SIGINT", ...), set once
        self._stop_ease_s = EASE_S
        self._stop_max_ease_s = MAX_EASE_S
        self._hurry = threading.Event()  # a second Ctrl-C: straight to neutral at the caps, then torque off
        self._hurry_fn: Callable[[], bool] | None = None
        self.error: BaseException | None = None
        self.report: StopReport | None = None
        self._frame_cond = threading.Condition()
        self._last_trace: FrameTrace | None = None
        self._prev_sent: dict[int, int] | None = None
        self._last_snapshot_seen: ChainSnapshot | None = None
        self._view: dict[str, TrackView] = self.tracks.view(0.0)
        self._sleep_fn = sleep
        self.loop = FixedRateLoop(self._frame, self.rate_hz, clock=self.clock, sleep=self._sleep, max_sleep_s=0.05)
        if self.driver is not None:
            self.driver.hand_over()  # the loop thread becomes its owner
        self._name = name
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._started = False
        self._pausing = False
        self._paused = False
        self._resumed = False
        if start:
            self.start()

    # -- life --------------------------------------------------------------------------------------
    def start(self) -> HeadService:
        with self._lock:
            if self._started:
                raise ServiceError("this service is already started")
            self._started = True
        self._thread.start()
        return self

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    @property
    def paused(self) -> bool:
        return self._paused

    def pause(self, timeout_s: float = 5.0) -> None:
        """Stop the loop at a frame boundary and release the bus to the caller's thread (manual work on
        ``pipeline`` / ``driver``: a calibration step, a test). Nothing is sent while paused; the servos
        hold their last goal. Commands submitted meanwhile (and an e-stop) apply when it resumes, the
        e-stop first. Not from the loop thread."""
        if threading.current_thread() is self._thread:
            raise ServiceError("pause: not from the loop thread")
        with self._lock:
            if self._paused or not self._started or self._closing:
                return
            self._pausing = True
        self.loop.stop()
        self._wake.set()
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            raise ServiceError(f"pause: the loop did not stop within {timeout_s} s")
        with self._lock:
            self._pausing, self._paused = False, True

    def resume(self) -> None:
        """Give the bus back to the loop and go on (call from the thread that paused or used the driver)."""
        with self._lock:
            if not self._paused:
                return
            if self.driver is not None:
                self.driver.hand_over()
            self._paused = False
            self._resumed = True
            self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
        self._thread.start()

    @contextmanager
    def paused_loop(self) -> Iterator[HeadService]:
        """``with service.paused_loop(): ...`` pauses for the block and resumes after it."""
        was = self._paused
        self.pause()
        try:
            yield self
        finally:
            if not was:
                self.resume()

    def now_s(self) -> float:
        """Now on the service clock (seconds since the service was made, monotonic)."""
        return self.clock.now_s()

    def __enter__(self) -> HeadService:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()

    # -- observing ---------------------------------------------------------------------------------
    def subscribe(self, kind: str, *, rate_hz: float | None = None, maxlen: int = 256) -> Subscription[Any]:
        """A bounded drop-oldest queue of ``kind`` items (see :mod:`.observers`)."""
        return self.observers.subscribe(kind, rate_hz=rate_hz, maxlen=maxlen)

    def status(self) -> ServiceStatus:
        s = self.loop.stats
        return ServiceStatus(
            self.now_s(),
            self.running,
            self._latched,
            self._torque_on,
            s.frames,
            s.late,
            s.missed,
            dict(self._view),
            "" if self.error is None else f"{type(self.error).__name__}: {self.error}",
        )

    @property
    def loop_stats(self) -> LoopStats:
        return self.loop.stats

    def telemetry(self) -> ChainSnapshot | None:
        """The driver's snapshot after the last frame (None offline or before the first)."""
        return self.pipeline.last_snapshot

    @property
    def last_trace(self) -> FrameTrace | None:
        return self._last_trace

    def wait_frame(self, after_index: int = -1, timeout_s: float = 1.0) -> FrameTrace | None:
        """The first frame whose index is above ``after_index`` (None on timeout or a stopped loop)."""
        deadline = time.monotonic() + timeout_s
        with self._frame_cond:
            while True:
                last = self._last_trace
                if last is not None and last.index > after_index:
                    return last
                left = deadline - time.monotonic()
                if left <= 0 or not self.running:
                    return None
                self._frame_cond.wait(min(left, 0.05))

    def wait_settled(self, after_index: int = -1, timeout_s: float = 2.0) -> bool:
        """Wait for a frame (after ``after_index``) the gate passed whole, or one that made no progress
        (a pose the gate keeps refusing): the servos are where the mix asks, or as close as allowed."""
        deadline = time.monotonic() + timeout_s
        with self._frame_cond:
            while True:
                last = self._last_trace
                if last is not None and last.index > after_index:
                    if last.goals_sent == last.goals_requested or last.goals_sent == self._prev_sent:
                        return True
                left = deadline - time.monotonic()
                if left <= 0 or not self.running or not self._motion_allowed():
                    return False
                self._frame_cond.wait(min(left, 0.05))

    # -- submitting --------------------------------------------------------------------------------
    def _submit(
        self, kind: str, apply: Callable[[CommandHandle, float], None], *, track: str | None = None,
        at_s: float | None = None, motion: bool = True, internal: bool = False,
    ) -> CommandHandle:  # fmt: skip
        handle = CommandHandle(kind, track, at_s)
        with self._lock:
            if (self._closing and not internal) or self._stop_requested or not self._started:
                state = "shut down" if self._started else "not started"
                raise ServiceClosedError(f"{kind}: the head service is {state}")
            if self.error is not None:
                raise ServiceClosedError(f"{kind}: the head service stopped on an error: {self.error}")
            if motion and self._latched:
                raise EStopLatchedError(f"{kind}: the e-stop is latched; clear_estop() then torque_on() first")
            if motion and not self._torque_wanted and self.driver is not None:
                raise ServiceError(f"{kind}: torque is off; torque_on() first")
            self._inbox.append((handle, lambda t: apply(handle, t)))
        return handle

    def _track(self, track: object) -> str:
        if not isinstance(track, str) or track not in self.tracks.slots:
            raise ServiceError(f"track: expected one of {list(self.tracks.slots)}, got {track!r}")
        return track

    def _start_time(self, at_s: object) -> float:
        """``at_s`` checked, or now (the submit time: a transition starts when it was asked for, so the
        first frame after it is already on its way)."""
        return self.now_s() if at_s is None else check_time_s(at_s, field="at_s")

    def _place(self, kind: str, track: str, at_s: float, source_for: Callable[[Slot, float], Source]) -> CommandHandle:
        """Schedule a source on ``track`` from ``at_s`` (service time); ``source_for(slot, t0_s)``
        builds it at its start (from what the track has then, where that matters)."""

        def apply(handle: CommandHandle, t_s: float) -> None:
            def activate(slot: Slot, t0_s: float) -> None:
                slot.install(source_for(slot, t0_s), handle, t0_s, self._notify)

            self.tracks.schedule(track, at_s, handle, activate)

        return self._submit(kind, apply, track=track, at_s=at_s)

    def play(
        self,
        what: Any,
        *,
        track: str = "face",
        at_s: float | None = None,
        duration_s: float | None = None,
        then: str | None = None,
    ) -> CommandHandle:
        """Play a script (a Script, a .toml path or a shipped name), a Timeline, a Recording or a Clip on
        ``track`` from ``at_s`` (service time; None = the next frame), for at most ``duration_s``; at the
        end hold the last pose (``then="hold"``, the default but for a clip, which does what its ``holds``
        says) or release the track (``"release"``). Done at its end. What the head cannot show is refused
        here (`commands.play_source`): ServiceError naming the expression, its track and the AU."""
        the_track = self._track(track)
        source, _ = play_source(
            self.head, self.validator, what, duration_s, check_then(then), self.pipeline.targets_for
        )
        return self._place("play", the_track, self._start_time(at_s), lambda slot, t0: source)

    def express(
        self,
        name: str,
        *,
        intensity: float = 1.0,
        transition_s: float = 0.5,
        hold_s: float = 1.0,
        track: str = "face",
        at_s: float | None = None,
    ) -> CommandHandle:
        """Move ``track`` to a named expression's apex (scaled by ``intensity``) over ``transition_s`` and
        hold it; done after ``hold_s`` (the pose stays until something else plays there)."""
        apex = expression_apex(self.head, name, intensity)
        source = pose_source(self.validator, apex, transition_s, hold_s, 0.0, name=str(name))
        self._on_head(apex, f"expression {name!r} at intensity {intensity!r}")
        return self._place("express", self._track(track), self._start_time(at_s), lambda slot, t0: source)

    def set_aus(
        self,
        aus: Mapping[str, float],
        *,
        track: str = "studio",
        transition_s: float = 0.3,
        hold_s: float = 0.0,
        merge: bool = False,
        at_s: float | None = None,
    ) -> CommandHandle:
        """Set ``track``'s AUs to ``aus`` over ``transition_s`` (minimum jerk); AUs the track had and
        ``aus`` does not name go to 0, or stay with ``merge=True`` (one slider moved). Done after the
        transition and ``hold_s``; the pose stays. On "studio" (an override track) the AUs set win outright."""
        source = pose_source(self.validator, aus, transition_s, hold_s, 0.0)
        self._on_head(self.validator.pose(dict(aus), where="set_aus"), "set_aus")
        the_track, start = self._track(track), self._start_time(at_s)
        if not merge:
            return self._place("set_aus", the_track, start, lambda slot, t0: source)
        wanted = self.validator.pose(dict(aus), where="set_aus")
        transition, hold = float(transition_s), float(hold_s)

        def merged(slot: Slot, t0_s: float) -> Source:  # the track's targets, with these AUs changed
            clip = transition_clip({**slot.targets(t0_s), **wanted}, transition, hold, name="set_aus")
            return ClipSource(clip, "set_aus")

        return self._place("set_aus", the_track, start, merged)

    def clear_aus(
        self,
        names: Sequence[str] | None = None,
        *,
        track: str = "studio",
        transition_s: float = 0.3,
        at_s: float | None = None,
    ) -> CommandHandle:
        """Release ``names`` on ``track`` (None: all of them, the track empties) over ``transition_s``."""
        the_track = self._track(track)
        transition = max(check_duration_s(transition_s, field="transition_s"), self.period_s)
        if names is None:
            return self._place("clear_aus", the_track, self._start_time(at_s), lambda slot, t0: _release(transition))
        gone = set(self.validator.pose({n: 0.0 for n in names}, where="clear_aus"))

        def source_for(slot: Slot, t0_s: float) -> Source:  # built at the start, from the track's targets
            keep = {au: v for au, v in slot.targets(t0_s).items() if au not in gone}
            return ClipSource(transition_clip(keep, transition, 0.0, name="clear_aus"), "clear_aus")

        return self._place("clear_aus", the_track, self._start_time(at_s), source_for)

    def look_at(
        self, point_mm: tuple[float, float, float] | None, *, track: str = "gaze", at_s: float | None = None
    ) -> CommandHandle:
        """Shift the gaze to ``point_mm`` (head frame, mm: +x the head's left, +y up, +z ahead; None =
        straight ahead): the eyes saccade, the neck follows, the eyes counter-rotate. Done when it lands."""
        the_track = self._track(track)
        target = None if point_mm is None else check_point_mm(point_mm)
        face_type = self.head.face_type

        def apply(handle: CommandHandle, t_s: float) -> None:
            def activate(slot: Slot, t0_s: float) -> None:
                if not isinstance(slot.source, GazeSource):
                    slot.install(GazeSource(face_type), handle, t0_s, self._notify)
                else:
                    slot.replace(handle, t0_s, self._notify, f"gaze moved on by #{handle.id}")
                assert isinstance(slot.source, GazeSource)
                slot.source.look_at(t0_s, target)

            self.tracks.schedule(the_track, start, handle, activate)

        start = self._start_time(at_s)
        return self._submit("look_at", apply, track=the_track, at_s=start)

    def follow(
        self,
        source: Any,
        *,
        track: str = "stream",
        duration_s: float | None = None,
        until: Callable[[], bool] | None = None,
        then: str = "hold",
        at_s: float | None = None,
    ) -> CommandHandle:
        """Follow a live source (``StreamSource``) on ``track`` every frame for ``duration_s`` (None: until
        stopped) or until ``until()`` is true (checked each frame on the loop thread: keep it cheap)."""
        the_track = self._track(track)
        if not callable(getattr(source, "sample", None)):
            raise ServiceError(f"follow: source must have sample(t_s) -> AUFrame, got {source!r}")
        theirs = getattr(source, "face_type", None)
        if theirs is not None and theirs != self.head.face_type:
            raise ServiceError(f"follow: the source is for a {theirs} face; head is {self.head.face_type}")
        limit = None if duration_s is None else check_duration_s(duration_s, field="duration_s", allow_zero=False)
        if until is not None and not callable(until):
            raise ServiceError(f"follow: until must be a callable returning bool, got {until!r}")
        mode = check_then(then) or "hold"
        return self._place(
            "follow", the_track, self._start_time(at_s), lambda slot, t0: FollowSource(source, limit, until, mode)
        )

    def speak(self, what: Any, *, at_s: float | None = None, duration_s: float | None = None) -> CommandHandle:
        """The speech slot: play visemes (a Clip, Timeline or Script) on the "speech" track, which owns the
        AUs it drives (the mouth) while the other tracks keep the rest of the face."""
        return self.play(what, track="speech", at_s=at_s, duration_s=duration_s, then="release")

    def set_alive(self, *, blink: bool | None = None, idle: bool | None = None, seed: int = 0) -> CommandHandle:
        """Switch the alive layers on or off (None: leave as is): spontaneous blinks, idle head/eye motion."""
        from servoface.controller.alive import BlinkLayer, IdleLayer

        for name, value in (("blink", blink), ("idle", idle)):
            if value is not None and not isinstance(value, bool):
                raise ServiceError(f"set_alive: {name} must be True, False or None, got {value!r}")
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ServiceError(f"set_alive: seed must be an integer, got {seed!r}")
        layers = {"blink": BlinkLayer(self.head.face_type, seed), "idle": IdleLayer(self.head.face_type, seed)}

        def apply(handle: CommandHandle, t_s: float) -> None:
            for name, value in (("blink", blink), ("idle", idle)):
                if value is None or name not in self.tracks.slots:
                    continue
                slot = self.tracks.slots[name]
                if value:
                    slot.install(AliveSource(layers[name], name), handle, t_s, self._notify)
                elif slot.source is not None:
                    slot.install(_release(self.period_s * 5), handle, t_s, self._notify)
            if handle._set(Status.DONE, t_s):
                self._notify(handle)

        return self._submit("set_alive", apply)

    def stop(self, track: str, *, release_s: float = 0.3, hold: bool = False) -> CommandHandle:
        """Stop what plays on ``track`` (and what is scheduled there): release it to nothing over
        ``release_s`` (0: at once), or with ``hold=True`` freeze it where it is."""
        the_track = self._track(track)
        release = check_duration_s(release_s, field="release_s")

        def apply(handle: CommandHandle, t_s: float) -> None:
            slot = self.tracks.slots[the_track]
            for p in slot.pending:
                if p.handle._set(Status.CANCELLED, t_s, f"stopped by #{handle.id}"):
                    self._notify(p.handle)
            slot.pending.clear()
            if slot.source is None:
                pass
            elif hold:
                pose = dict(slot.last)
                slot.install(ClipSource(transition_clip(pose, 0.0, 0.0, merge=True, name="hold"), "hold"),
                             handle, t_s, self._notify)  # fmt: skip
            elif release <= 0:
                slot.clear(t_s, f"stopped by #{handle.id}", self._notify)
            else:
                slot.install(_release(release), handle, t_s, self._notify)
                return  # done when the release has finished
            if handle._set(Status.DONE, t_s):
                self._notify(handle)

        return self._submit("stop", apply, track=the_track, motion=False)

    def neutral(self, transition_s: float = 0.6) -> CommandHandle:
        """Release every track (alive layers too) to neutral over ``transition_s``; done when all are."""
        transition = max(check_duration_s(transition_s, field="transition_s"), self.period_s)
        return self._submit("neutral", lambda h, t: self._apply_neutral(h, t, transition))

    def _apply_neutral(self, handle: CommandHandle, t_s: float, transition_s: float) -> None:
        busy = False
        for slot in self.tracks.slots.values():
            for p in slot.pending:
                if p.handle._set(Status.CANCELLED, t_s, f"neutral #{handle.id}"):
                    self._notify(p.handle)
            slot.pending.clear()
            if slot.source is not None:
                slot.install(_release(transition_s), handle, t_s, self._notify)
                busy = True
        if handle._set(Status.RUNNING, t_s):
            self._notify(handle)
        if not busy and handle._set(Status.DONE, t_s):
            self._notify(handle)

    def torque_on(self) -> CommandHandle:
        """Torque on: every goal pinned to where its servo is first; then the head eases (under the gate's
        caps) to the mixed pose. Refused while the e-stop is latched."""
        with self._lock:
            if self._latched:
                raise EStopLatchedError("torque_on: the e-stop is latched; clear_estop() first")
            self._torque_wanted = True
        return self._submit("torque_on", self._apply_torque_on, motion=False)

    def torque_off(self) -> CommandHandle:
        """Torque off on every servo (the head goes limp); every track is cleared."""
        with self._lock:
            self._torque_wanted = False
        return self._submit("torque_off", self._apply_torque_off, motion=False)

    def estop(self, reason: str = "") -> CommandHandle:
        """Emergency stop, from any thread: the loop stops sending goals at once (the servos hold their
        last goal), clears every track and turns torque off on every servo; latched until
        :meth:`clear_estop`. Done when torque is off. Never refused, takes no lock (safe in a signal
        handler): flags, an append and two events."""
        handle = CommandHandle("estop")
        handle.detail = str(reason)
        self._latched = True
        self._torque_wanted = False
        self._estop_handle = handle
        self._estop_pending.append(handle)
        self._estop_requested.set()
        self._wake.set()
        if not self.running and not self._paused:  # no loop to do it: the owner is gone; report it
            handle._set(Status.FAILED, self.now_s(), "the loop is not running")
        return handle

    @property
    def estop_latched(self) -> bool:
        return self._latched

    def clear_estop(self) -> CommandHandle:
        """Unlatch the e-stop (torque stays off: call :meth:`torque_on` to move again)."""
        with self._lock:
            pending = self._estop_handle
        if pending is not None:
            pending.wait(1.0)

        def apply(handle: CommandHandle, t_s: float) -> None:
            with self._lock:
                self._latched = False
                self._estop_handle = None
            self.observers.offer("fault", ServiceEvent(t_s, "estop_cleared"))
            if handle._set(Status.DONE, t_s):
                self._notify(handle)

        return self._submit("clear_estop", apply, motion=False)

    # -- the loop thread ---------------------------------------------------------------------------
    def _notify(self, handle: CommandHandle) -> None:
        if self.observers.wants("playback"):
            self.observers.offer("playback", handle._event())

    def _motion_allowed(self) -> bool:
        return not self._latched and (self._torque_on or self.driver is None)

    def _sleep(self, dt_s: float) -> None:
        if self._sleep_fn is not None:
            self._sleep_fn(dt_s)
            woke = self._wake.is_set()
        else:
            woke = self._wake.wait(dt_s)
        if woke:
            self._wake.clear()
            if self._estop_requested.is_set():
                self._apply_estop(self.clock.now_s())

    def _run(self) -> None:
        try:
            if self._estop_requested.is_set():  # pressed while paused
                self._apply_estop(self.clock.now_s())
            if self._resumed:
                self._repin()
            self.loop.run()
        except BaseException as err:  # an unexpected crash still goes through the stop below
            self.error = err
        finally:
            if self._pausing and self.error is None and not self._stop_requested:
                if self.driver is not None:
                    self.driver.hand_over()
            else:
                self._finish()

    def _frame(self, tick: Tick) -> bool | None:
        t = tick.due_s
        if self._estop_requested.is_set():
            self._apply_estop(t)
        signals = stop_signals.active()
        if signals is not None and signals.requested:  # SIGINT / SIGTERM / SIGHUP under the CLI: the stop path
            if self._stop_reason is None:
                self._stop_reason = signals.name or "signal"
            return False
        if self._pausing:  # (loop.stop() alone could be undone by a run() that is only starting)
            return False
        if not self._drain(t) or self._stop_requested:
            return False
        trace: FrameTrace | None = None
        done: list[CommandHandle] = []  # commands whose sources finished this frame: completed once published
        try:
            if self._motion_allowed():
                self.tracks.activate_due(t, self._notify)
                aus = self.tracks.sample(t, self._notify)
                try:
                    frame = self.validator(t, aus)
                except ControllerError as err:  # cannot happen with validated sources; hold, say so
                    self.observers.offer("fault", ServiceEvent(t, "bad_mix", str(err)))
                    self._refused(t, err)
                else:
                    try:
                        trace = self.pipeline.step(frame, t, late_s=tick.late_s)
                    except (ControllerError, SimError) as err:  # the head refuses this pose: nothing was sent
                        self.observers.offer("fault", ServiceEvent(t, "frame_error", str(err)))
                        self._refused(t, err)
                done = self.tracks.advance(t)
            elif self.driver is not None:  # torque off / e-stop: no goals, telemetry goes on
                self.pipeline.last_snapshot = self.driver.read_state()
        except HardwareError as err:
            self._complete(done, t)
            self._bus_failed(t, err)
            return False
        except (ControllerError, SimError) as err:
            self.observers.offer("fault", ServiceEvent(t, "frame_error", str(err)))
        try:
            self._publish(t, tick, trace)
        finally:
            self._complete(done, t)
        snap = self.pipeline.last_snapshot
        if self.stop_on_port_failure and snap is not None and not snap.bus_connected:
            self._bus_failed(
                t, BusDisconnectedError(f"the port failed ({bus_problem(snap)}); stopped, no blind driving")
            )
            return False
        return None

    def _on_head(self, aus: Mapping[str, float], what: str) -> None:
        """A pose the head's own face model refuses (an intensity outside its AU table's range, its direct
        table or muscles) is bad input: ServiceError at once, naming ``what`` and the AU, nothing scheduled.
        (A mix of poses the head takes one by one can still be refused in a frame: `_refused`.)"""
        why = pose_refusal(self.pipeline.targets_for, aus, what, self.head.name)
        if why is not None:
            raise ServiceError(why)

    def _refused(self, t_s: float, err: Exception) -> None:
        """A frame whose mixed pose the head refused (nothing of it sent): the commands that asked for it
        fail with the reason (`TrackTable.fail_refused`: a waiter is told, not left waiting), and the last
        safe goals are sent again, so the servos hold where they are and the bus, and each servo's Bus
        Watchdog, stay fed. (HardwareError from that write goes to the caller's bus-failure path.)"""
        self.tracks.fail_refused(t_s, err, self._notify, self.pipeline.targets_for, (ControllerError, SimError))
        self.pipeline.hold()

    def _complete(self, handles: list[CommandHandle], t_s: float) -> None:
        """Commands whose sources finished at ``t_s``, DONE after that frame is published (`_frame`): a
        waiter woken by it reads that frame's status and trace, not the one before."""
        for handle in handles:
            if handle._set(Status.DONE, t_s):
                self._notify(handle)

    def _drain(self, t_s: float) -> bool:
        while True:
            try:
                handle, apply = self._inbox.popleft()
            except IndexError:
                return True
            if handle.status.final:
                continue
            try:
                apply(t_s)
            except HardwareError as err:
                handle._set(Status.FAILED, t_s, str(err), err)
                self._bus_failed(t_s, err)
                return False
            except ControllerError as err:
                if handle._set(Status.FAILED, t_s, str(err), err):
                    self._notify(handle)

    def _publish(self, t_s: float, tick: Tick, trace: FrameTrace | None) -> None:
        hub = self.observers
        if trace is not None:
            hub.offer("trace", trace, t_s)
            hub.offer_lazy(
                "frame",
                lambda: FrameSummary(
                    trace.index, t_s, trace.verdict, trace.checks, trace.reasons, dict(trace.timings_ms),
                    tick.late_s, tick.missed_before,
                ),
                t_s,
            )  # fmt: skip
        snap = self.pipeline.last_snapshot
        if snap is not None and snap is not self._last_snapshot_seen:
            self._last_snapshot_seen = snap
            hub.offer("telemetry", snap, t_s)
            for event in snap.events:
                hub.offer("fault", event, t_s)
        self._view = self.tracks.view(t_s)
        with self._frame_cond:
            if trace is not None:
                self._prev_sent = None if self._last_trace is None else self._last_trace.goals_sent
                self._last_trace = trace
            self._frame_cond.notify_all()

    def _torque_off_all(self) -> bool:
        """Torque off on every servo (each retried, carrying on past failures; the driver's stop policy), the
        whole pass repeated for the servos not reached; True when every servo confirmed it."""
        if self.driver is None:
            return True
        unreached: tuple[int, ...] = ()
        for _ in range(TORQUE_RETRIES):
            unreached = self.driver.torque_off(unreached or None)
            if not unreached:
                break
        self._torque_on = False
        return not unreached

    def _apply_estop(self, t_s: float) -> None:
        self._estop_requested.clear()
        handle = self._estop_handle
        kept: deque[tuple[CommandHandle, Callable[[float], None]]] = deque()
        while self._inbox:  # commands submitted before the e-stop are void; clear/torque ones stay
            item = self._inbox.popleft()
            if item[0].kind in ("clear_estop", "torque_off", "stop"):
                kept.append(item)
            elif item[0]._set(Status.CANCELLED, t_s, "e-stop"):
                self._notify(item[0])
        self._inbox.extendleft(reversed(kept))
        self.tracks.clear_all(t_s, "e-stop", self._notify)
        self._view = self.tracks.view(t_s)  # before the presses complete: status() then shows empty tracks
        ok = self._torque_off_all()
        detail = "torque off" if ok else "torque off FAILED on some servos"
        # the presses answered here, by their reasons (a pending press's detail is its reason until it is done)
        reasons = list(dict.fromkeys(p.detail for p in self._estop_pending if p.detail))
        if not reasons and handle is not None and handle.detail:
            reasons = [handle.detail]
        said = f"{detail} ({', '.join(reasons)})" if reasons else detail
        self.observers.offer("fault", ServiceEvent(t_s, "estop", said))
        while self._estop_pending:  # every press so far is answered by this torque-off
            press = self._estop_pending.popleft()
            if press._set(Status.DONE if ok else Status.FAILED, self.clock.now_s(), detail):
                self._notify(press)

    def _repin(self) -> None:
        """After a pause the bus may have carried other goals: take what the driver last put on the wire
        (or, for a servo without one, where it is) as the last command, so the first frame is rate-checked
        from there and never jumps."""
        self._resumed = False
        if self.driver is None:
            return
        snapshot = self.driver.read_state()
        lo_hi = self.pipeline.calibration.position_limits_tick()
        goals: dict[int, int] = {}
        for sid, state in snapshot.servos.items():
            if sid not in lo_hi:
                continue
            tick = state.goal_tick if state.goal_tick is not None else state.position_tick
            if tick is not None:
                goals[sid] = min(max(int(tick), lo_hi[sid][0]), lo_hi[sid][1])
        self.pipeline.pin_to(goals)
        self.pipeline.gate.reset()
        self.pipeline.last_snapshot = snapshot

    def _apply_torque_on(self, handle: CommandHandle, t_s: float) -> None:
        if self._latched:
            raise EStopLatchedError("torque_on: the e-stop is latched")
        if self.driver is not None:
            self.driver.torque_on()
            snapshot = self.driver.read_state()
            lo_hi = self.pipeline.calibration.position_limits_tick()
            present = {s: min(max(p, lo_hi[s][0]), lo_hi[s][1]) for s, p in snapshot.positions_tick().items()}
            self.pipeline.pin_to(present)
            self.pipeline.gate.reset()
            self.pipeline.last_snapshot = snapshot
        self._torque_on = True
        if handle._set(Status.DONE, t_s):
            self._notify(handle)

    def _apply_torque_off(self, handle: CommandHandle, t_s: float) -> None:
        self.tracks.clear_all(t_s, f"torque off #{handle.id}", self._notify)
        self._view = self.tracks.view(t_s)  # before the handle completes: status() then shows empty tracks
        ok = self._torque_off_all()
        handle._set(Status.DONE if ok else Status.FAILED, t_s, "" if ok else "torque off failed on some servos")
        self._notify(handle)

    def _bus_failed(self, t_s: float, err: HardwareError) -> None:
        self.error = err
        self.observers.offer("fault", ServiceEvent(t_s, "bus_failure", str(err)))

    # -- stopping ----------------------------------------------------------------------------------
    def shutdown(
        self,
        *,
        ease_s: float = EASE_S,
        max_ease_s: float = MAX_EASE_S,
        reason: str = "end",
        hurry: Callable[[], bool] | None = None,
        timeout_s: float = STOP_TIMEOUT_S,
    ) -> StopReport:
        """The safe stop, through the one stop path (:func:`servoface.controller.safe_stop.safe_stop`, run on
        the loop thread as it exits): ease from the mixed pose to neutral through the gate (``ease_s``, at most
        ``max_ease_s``; skipped after an e-stop, with torque off or after a bus failure; :meth:`hurry`,
        ``hurry()`` or a second stop signal turn it into the fastest move to neutral the gate's caps allow),
        then torque off on every servo (retried, carrying on past failures) and the Bus Watchdog disarmed,
        then the bus closed.

        Returns the :class:`~servoface.controller.safe_stop.StopReport` (kept as ``service.report``): ``unreached``
        names servos whose torque-off was not confirmed. Safe to call twice and from any thread but the loop's
        (the second call returns the first report)."""
        if threading.current_thread() is self._thread:
            raise ServiceError("shutdown: not from the loop thread")
        with self._lock:
            already = self._closing
            self._closing = True
            if not already:
                self._stop_ease_s = _seconds(ease_s, EASE_S)
                self._stop_max_ease_s = _seconds(max_ease_s, MAX_EASE_S)
                self._hurry_fn = hurry
                if self._stop_reason is None:
                    self._stop_reason = str(reason)
            self._stop_requested = True
        if self._paused:
            self.resume()
        self._wake.set()
        if self._started:
            self._thread.join(timeout_s)
        elif not already:
            self._finish()
        if self.report is not None:
            return self.report
        ids = () if self.driver is None else tuple(self.driver.servo_ids)
        why = f"the loop thread did not finish the stop within {timeout_s:g} s"
        return StopReport(self._stop_reason or str(reason), False, 0.0, why, ids, error=why)

    def hurry(self) -> None:
        """Hurry the stop (a second Ctrl-C): straight to neutral at the gate's caps (at most
        ``safe_stop.HURRY_S``), then torque off — never cut mid-pose; from any thread."""
        self._hurry.set()

    def shutdown_async(self, *, ease_s: float = EASE_S) -> CommandHandle:
        """:meth:`shutdown` on a helper thread; the handle is done when the head is stopped (failed if
        torque-off was not confirmed). For front ends that must not block (a network request)."""
        handle = CommandHandle("shutdown")

        def run() -> None:
            report = self.shutdown(ease_s=ease_s)
            ok = report.safe and not report.error
            detail = report.error or ("" if report.safe else f"torque off not confirmed on {list(report.unreached)}")
            handle._set(Status.DONE if ok else Status.FAILED, self.now_s(), detail)

        handle._set(Status.RUNNING, self.now_s())
        threading.Thread(target=run, name=f"{self._name}-shutdown", daemon=True).start()
        return handle

    def _hurried(self) -> bool:
        if self._hurry.is_set():
            return True
        signals = stop_signals.active()
        if signals is not None and signals.hurry:
            return True
        return self._hurry_fn is not None and bool(self._hurry_fn())

    def _finish(self) -> None:
        """On the loop thread as it exits (however it exits): end every command, then the one stop path
        (ease to neutral, torque off, watchdog disarmed, bus closed), then end every observer."""
        t = self.clock.now_s()
        self._closing = True
        with self._lock:
            self._stop_requested = True
            inbox = list(self._inbox)
            self._inbox.clear()
        error = self.error
        if self._stop_reason is None:
            self._stop_reason = (
                "end" if error is None else "bus failure" if isinstance(error, HardwareError) else "error"
            )
        reason = self._stop_reason
        signals = stop_signals.active()
        if signals is not None and signals.requested and reason in ("end", "error"):
            reason = signals.name or reason  # a signal came while the caller was stopping: say so
        why = "service stopped" if error is None else f"service stopped: {error}"
        for handle, _ in inbox:
            if handle._set(Status.CANCELLED, t, why):
                self._notify(handle)
        for slot in self.tracks.slots.values():
            for p in slot.pending:
                p.handle._set(Status.FAILED if error else Status.CANCELLED, t, why, error)
            slot.pending.clear()
            if slot.handle is not None:
                slot.handle._set(Status.FAILED if error else Status.CANCELLED, t, why, error)
        error_text = "" if error is None else f"{type(error).__name__}: {error}"
        skip = ""
        if isinstance(error, HardwareError):
            skip = "the bus failed"
        elif self._latched:
            skip = "e-stop"
        elif not self._torque_on:
            skip = "torque was off"
        elif self._stop_ease_s <= 0:
            skip = "not asked"
        last = self._last_trace
        try:
            report = safe_stop(
                self.pipeline,
                self.driver,
                from_aus=None if last is None else last.aus,
                ease=not skip,
                ease_s=self._stop_ease_s,
                max_ease_s=self._stop_max_ease_s,
                hurry=self._hurried,
                reason=reason,
                on_frame=lambda trace: self.observers.offer("trace", trace, self.clock.now_s()),
                error=error_text,
                skip_note=skip,
            )
        except BaseException as err:  # noqa: BLE001 - the report must say the stop itself failed
            ids = () if self.driver is None else tuple(self.driver.servo_ids)
            text = f"the stop failed: {type(err).__name__}: {err}"
            report = StopReport(reason, False, 0.0, text, ids, error=error_text or text)
        self._torque_on = False
        self.report = replace(report, error=report.error or error_text)
        with self._frame_cond:
            self._frame_cond.notify_all()
        self.observers.close_all()


def _seconds(value: object, default: float) -> float:
    """A finite duration >= 0 (bad values fall back to ``default``: a stop never refuses to stop)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not value == value or value < 0:
        return default
    return min(float(value), 3600.0)


def _release(transition_s: float) -> ClipSource:
    return ClipSource(transition_clip({}, transition_s, 0.0, name="release"), "release")
