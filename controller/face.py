"""`Face`: the ten-line Python API. Open a head on a port or on the emulator, set AUs or an expression,
play a script, look at a point, close safely.

    from servoface.controller.face import Face

    with Face.open("human", emulate=True) as face:      # or Face.open("my_head/", port="/dev/ttyUSB0")
        face.express("happiness", hold_s=1.0)
        face.set_aus({"AU1": 0.6, "AU2": 0.6}, transition_s=0.3)
        face.look_at((150.0, 40.0, 600.0))              # mm, head frame: +x the head's left, +y up, +z ahead
        face.play("controller/scripts/human_performance.toml")
    # leaving the block eases to neutral, turns torque off and closes the port

Every call runs the fixed-rate loop in the calling thread (which therefore owns the bus) until its motion
is done; every frame passes the twin gate. ``face.traces`` keeps the recent frame traces.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

from servoface.calibration import HeadCalibration, load_calibration
from servoface.controller import stop_signals
from servoface.controller.alive.gaze import gaze_config_for, solve_look_at
from servoface.controller.alive.gaze_layer import angles_to_aus
from servoface.controller.errors import ControllerError
from servoface.controller.frame import AUFrame, FrameValidator
from servoface.controller.head_servos import servo_specs, temperature_limits_c
from servoface.controller.performance import Performance, Samples, play_timeline
from servoface.controller.pipeline import Pipeline
from servoface.controller.safe_stop import EASE_S, MAX_EASE_S, StopReport, bus_problem, safe_stop
from servoface.controller.script import Script, load_script
from servoface.controller.timeline import ChannelClip, Key, Timeline, min_jerk
from servoface.controller.trace_ring import TraceRing
from servoface.controller.values import as_finite, check_seconds, printable_repr
from servoface.hardware.bus import ServoBus, open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.fault_policy import FaultPolicy
from servoface.sim.expressions import load_library
from servoface.sim.head import Head
from servoface.sim.heads import load_head

_GAZE_AUS = frozenset({"AU51", "AU52", "AU53", "AU54", "AU55", "AU56", "AU61", "AU62", "AU63", "AU64"})
_DOG_GAZE_AUS = frozenset({"AU9", "AU10", "AU11", "AU12", "AU13"})


def head_calibration(head: Head, calibration: HeadCalibration | str | Path | None = None) -> HeadCalibration:
    """The calibration given, or the one the head profile names."""
    if isinstance(calibration, HeadCalibration):
        return calibration
    path = calibration if calibration is not None else head.calibration_path
    if path is None:
        raise ControllerError(
            f"head {head.name!r} names no calibration file; run `servoface calibrate --head ...` first"
        )
    return load_calibration(path)


SETTLE_MAX_S = 2.0  # longest a call keeps walking the servos to its final frame after the timeline ends
SETTLE_CHUNK_S = 0.1


class _Still:
    """The same AU frame at every time (holding a pose on the loop)."""

    def __init__(self, frame: AUFrame) -> None:
        self._aus = dict(frame.aus)

    def sample(self, t_s: float) -> AUFrame:
        return AUFrame(t_s, self._aus)


class Face:
    """A head driven through the whole pipeline. Build it with `Face.open`."""

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
        self.traces = TraceRing(maxlen=history)  # the newest frames; ``.sink`` may stream every one
        self._closed = False
        self.stop_report: StopReport | None = None

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
        fast_sync_read: bool = False,
        policy: FaultPolicy | None = None,
    ) -> Face:
        """Open ``head`` (built-in name, profile folder, or a loaded Head) on ``port`` or on the emulator.

        The servos are configured from the profile and calibration (EEPROM only with torque off, limits
        written as a hardware backstop), torque goes on with goals pinned to present positions, and the
        pipeline starts from where the servos are.
        """
        if (port is None) == (not emulate):
            raise ControllerError("Face.open: give exactly one of port='/dev/ttyUSB0' or emulate=True")
        the_head = head if isinstance(head, Head) else load_head(head)
        cal = head_calibration(the_head, calibration)
        specs = servo_specs(the_head, cal)
        chain = None
        if emulate:
            from servoface.hardware.emulator import ServoChain

            chain = ServoChain.create([(s.servo_id, s.model) for s in specs], baud=baud, wire_time=wire_time)
            for s in specs:  # the head powers up at rest
                chain.servo(s.servo_id).move_by_hand(cal.by_id(s.servo_id).neutral_tick)
            bus = open_bus("dynamixel", port=chain, baud=baud)
        else:
            bus = open_bus("dynamixel", port=port, baud=baud)
        driver: Driver | None = None
        try:
            driver = Driver(bus, specs, fast_sync_read=fast_sync_read, policy=policy)
            driver.configure()
            with stop_signals.interruptible():  # torque is off and the bus idle: a signal aborts at once
                pipeline = Pipeline(  # builds the gate's tables (seconds on a first run) before torque goes on
                    the_head,
                    cal,
                    driver=driver,
                    rate_hz=rate_hz,
                    temperature_limits_c=temperature_limits_c(specs),
                )
            stop_signals.raise_if_requested()
            driver.torque_on()
            snapshot = driver.read_state()
            lo_hi = cal.position_limits_tick()
            present = {
                sid: min(max(tick, lo_hi[sid][0]), lo_hi[sid][1]) for sid, tick in snapshot.positions_tick().items()
            }
            pipeline.pin_to(present)
            pipeline.last_snapshot = snapshot
            pipeline.last_write_s = time.monotonic()  # goals were just pinned: the first frame's caps run from now
        except BaseException:
            try:
                if driver is not None:  # whatever went wrong, every servo ends with torque off
                    driver.close(torque_off=True)
                else:
                    bus.close()
            finally:
                if chain is not None:
                    chain.close()
            raise
        return cls(the_head, pipeline, driver=driver, bus=bus, chain=chain)

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
    def _run(self, timeline: Timeline | Script, duration_s: float) -> Performance:
        self._check_open()
        perf = play_timeline(
            self.pipeline,
            timeline,
            duration_s,
            start_s=0.0,
            on_frame=self.traces.append,
            keep_traces=True,
            stop_on_interrupt=True,
        )
        self.t_s += duration_s
        if perf.traces:
            self.pose = dict(perf.traces[-1].aus)
            self._settle(perf)
        return perf

    def _settle(self, perf: Performance, max_s: float = SETTLE_MAX_S) -> None:
        """Keep sending the final frame while the gate is still walking the servos towards it.

        A motion faster than the servos' rate caps, or frames skipped on a busy machine, leave the last
        frame clipped short of its goal; without this the call would return (and `close` turn torque off)
        with the head somewhere on the way. Stops when the gate passes the frame whole, makes no progress
        (a pose it refuses), or after ``max_s``.
        """
        period_s = 1.0 / self.pipeline.rate_hz
        final = perf.traces[-1]
        frame = AUFrame(final.t_s, final.aus)
        source = _Still(frame)
        waited = 0.0
        stalled = 0  # chunks without progress (one frame may not move: the caps hold per second of wire time)
        while not perf.interrupted and perf.bus_failure is None and waited < max_s and stalled < 2:
            last = perf.traces[-1]
            if last.goals_sent == last.goals_requested:
                return
            before = last.goals_sent
            more = play_timeline(
                self.pipeline,
                source,
                SETTLE_CHUNK_S,
                start_s=final.t_s + period_s,
                on_frame=self.traces.append,
                keep_traces=True,
                stop_on_interrupt=True,
            )
            perf.traces.extend(more.traces)
            perf.interrupted = more.interrupted
            perf.bus_failure = more.bus_failure
            waited += SETTLE_CHUNK_S
            stalled = stalled + 1 if perf.traces[-1].goals_sent == before else 0

    def set_aus(self, aus: Mapping[str, float], *, transition_s: float = 0.4, hold_s: float = 0.0) -> Performance:
        """Move to the AU pose ``aus`` (AUs not named go to 0) over ``transition_s``, then hold."""
        if not isinstance(aus, Mapping):
            raise ControllerError(f"set_aus: aus must be a mapping of AU name -> intensity, got {type(aus).__name__}")
        pose = self.validator.pose(dict(aus), where="set_aus")
        transition = max(check_seconds(transition_s, "set_aus: transition_s"), 1.0 / self.pipeline.rate_hz)
        duration = transition + check_seconds(hold_s, "set_aus: hold_s")
        timeline = Timeline(self.head.face_type, initial_pose=self.pose)
        channels = {
            au: (Key(0.0, None), Key(transition, value, min_jerk), Key(duration, value)) for au, value in pose.items()
        }
        clip = ChannelClip(
            channels,
            duration,
            unlisted="to_zero",
            release_s=transition,
            release_easing=min_jerk,
            name="set_aus",
        )
        timeline.play(clip)
        return self._run(timeline, duration)

    def express(
        self, name: str, *, intensity: float = 1.0, transition_s: float = 0.5, hold_s: float = 1.0
    ) -> Performance:
        """Move to a named expression's apex (scaled by ``intensity``) and hold it."""
        library = load_library(self.head.expressions_path or self.head.face_type)
        if not isinstance(name, str) or name not in library:
            raise ControllerError(f"express: unknown expression {printable_repr(name)}; known: {sorted(library)}")
        level = as_finite(intensity)
        if level is None or not 0 <= level <= 1:
            raise ControllerError(f"express: intensity must be a number within 0..1, got {printable_repr(intensity)}")
        apex = {au: v * level for au, v in library[name].apex().items()}
        return self.set_aus(apex, transition_s=transition_s, hold_s=hold_s)

    def neutral(self, transition_s: float = 0.6) -> Performance:
        return self.set_aus({}, transition_s=transition_s)

    def look_at(self, point_mm: tuple[float, float, float], *, transition_s: float = 0.5) -> Performance:
        """Turn eyes and head towards a point (head frame, mm); eyes lead, the neck takes the rest."""
        values: tuple[Any, ...] = ()
        if isinstance(point_mm, tuple | list) and len(point_mm) == 3:
            values = tuple(point_mm)
        elif not isinstance(point_mm, str | bytes | Mapping):
            try:
                values = tuple(point_mm) if len(point_mm) == 3 else ()  # numpy arrays and the like
            except TypeError:  # not a sequence at all (a bare number, None, a set)
                values = ()
        numbers_mm = [as_finite(v) for v in values]
        if len(numbers_mm) != 3 or any(v is None or abs(v) > 1e6 for v in numbers_mm):
            raise ControllerError(
                f"look_at: point_mm must be three finite numbers (x, y, z) in mm, got {printable_repr(point_mm)}"
            )
        check_seconds(transition_s, "look_at: transition_s")
        cfg = gaze_config_for(self.head.face_type, self.head)
        gaze = solve_look_at(tuple(numbers_mm), cfg)  # type: ignore[arg-type]
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

    def play(self, script: Script | str | Path, *, duration_s: float | None = None) -> Performance:
        """Play a timeline script to its end (or for ``duration_s`` at most): a TOML file, a shipped
        script by name (``"human_performance"``, see ``servoface list scripts``) or a loaded Script."""
        loaded = script if isinstance(script, Script) else load_script(script)
        if loaded.face_type != self.head.face_type:
            raise ControllerError(
                f"script {loaded.source} is for a {loaded.face_type} face; "
                f"head {self.head.name!r} is {self.head.face_type}"
            )
        end_s = loaded.end_s
        if duration_s is not None:
            end_s = min(end_s, check_seconds(duration_s, "play: duration_s", minimum=1e-3))
        return self._run(loaded, end_s)

    def follow(self, source: Samples, duration_s: float | None = None) -> Performance:
        """Follow a live source (``servoface.controller.inputs.StreamSource``) or a recording for ``duration_s``
        (None = until Ctrl-C); the source's dropout policy decides what a gap in the data looks like."""
        from servoface.controller.inputs.follow import follow

        self._check_open()
        if duration_s is not None:
            duration_s = check_seconds(duration_s, "follow: duration_s", minimum=1e-3)
        perf = follow(
            self.pipeline,
            source,
            duration_s,
            on_frame=self.traces.append,
            stop_on_interrupt=True,
            until=lambda: bus_problem(self.pipeline.last_snapshot) is not None,
            keep_traces=True,
        )
        if perf.bus_failure is None:
            perf.bus_failure = bus_problem(self.pipeline.last_snapshot)
        if perf.traces:
            self.t_s += perf.traces[-1].t_s
            self.pose = dict(perf.traces[-1].aus)
        return perf

    def say(self, text: str, *, voice: str = "en-us", out_dir: str | Path | None = None) -> Performance:
        """Speak ``text`` (espeak-ng) with lip sync: the mouth on the speech track, the rest of the face as it
        is; the sound on the default output when there is one. ``out_dir``: also write speech.wav/.toml."""
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
        """The one stop path (`servoface.controller.safe_stop`): ease to neutral (at most ``max_ease_s``; not
        at all when ``ease_s`` is 0, or once ``hurry()`` — default: a second stop signal — turns true), torque
        off on every servo (retried, carrying on), Bus Watchdog disarmed, port (and emulator) closed.

        Returns the `StopReport` (also kept as ``face.stop_report``): ``report.unreached`` names servos whose
        torque-off was not confirmed. Safe to call twice (the second call returns the first report).
        """
        if self._closed:
            return self.stop_report
        signals = stop_signals.active()
        if hurry is None:
            hurry = (lambda: signals.hurry) if signals is not None else (lambda: False)
        try:
            if self.driver is not None:
                self.stop_report = safe_stop(
                    self.pipeline,
                    self.driver,
                    from_aus=self.pose,
                    ease=ease_s > 0,
                    ease_s=ease_s,
                    max_ease_s=max_ease_s,
                    hurry=hurry,
                    reason=reason,
                )
                self.pose = {}
            elif self.bus is not None:
                self.bus.close()
        finally:
            self._closed = True
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
        else:
            reason = f"error: {type(exc).__name__}"
        self.close(reason=reason)
