"""`Studio`: the studio's one object between the web layer and the head service. Every route and every
WebSocket message ends in one of its methods, with a validated body (:mod:`.models`); each becomes a
service command (or a bus job on the lender), so the studio holds no control logic of its own. It also
keeps what only the studio knows: the connected browsers, "hold" and the drop policy (the last browser
gone → ease to neutral within 1 s unless hold), manual mode and the calibration session."""

from __future__ import annotations

import re
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from servoface.controller.errors import ControllerError
from servoface.controller.service import CommandHandle, EStopLatchedError, HeadService, ServiceClosedError
from servoface.controller.studio import models as m
from servoface.controller.studio import views
from servoface.controller.studio.calibrate import CalibrationSession, idle_state
from servoface.controller.studio.errors import ConflictError, InvalidValueError, NotFoundError, StudioError
from servoface.controller.studio.lender import BusLender
from servoface.controller.studio.liveness import Liveness
from servoface.controller.studio.render import TwinImage, TwinRenderer
from servoface.controller.studio.scripts import ScriptFolder, build, sample, summary, text_of, toml_to_document
from servoface.hardware.driver import Driver
from servoface.hardware.errors import HardwareError
from servoface.hardware.snapshot import ChainSnapshot

DROP_NEUTRAL_S = 0.6  # ease to neutral this fast when the last browser goes (well inside 1 s)
MAX_JOG_STEP_TICK = 300  # as the calibration window: one manual move at most this far from the last goal
PAD_AHEAD_MM, PAD_ACROSS_MM, PAD_UP_MM = 600.0, 300.0, 200.0


@dataclass
class StudioOptions:
    out_dir: Path = field(default_factory=Path.cwd)
    scripts_dir: Path = field(default_factory=Path.cwd)
    render: bool = True
    width: int = 640
    height: int = 480


def _field_of(message: str, default: str) -> str:
    """``aus.AU99`` from the service's ``set_aus.AU99: ...`` (the AU at fault), else ``default``."""
    match = re.match(r"^[a-z_]+\.(AU[0-9]+[LR]?)\b", message)
    return f"{default}.{match.group(1)}" if match and default == "aus" else default


def _command(handle: CommandHandle) -> dict[str, Any]:
    return {"command": {"id": handle.id, "kind": handle.kind, "status": str(handle.status)}}


class Studio:
    """See the module docstring. ``notify(message)`` is called (any thread) with every state push."""

    def __init__(self, service: HeadService, options: StudioOptions | None = None) -> None:
        self.service = service
        self.options = options or StudioOptions()
        self.hold = False
        self.last_drop_s: float | None = None
        self.last_drop_reason = ""
        self.liveness = Liveness(self._last_browser_gone)
        self.listeners: list[Callable[[dict[str, Any]], None]] = []
        self.image_listeners: list[Callable[[TwinImage], None]] = []
        self._lock = threading.Lock()
        self.roles = {a.servo.id: a.role for a in service.head.actuators}
        self.lender = BusLender(service, on_snapshot=self._manual_snapshot, on_change=self.push_state)
        self.renderer: TwinRenderer | None = None
        if self.options.render:
            self.renderer = TwinRenderer(
                service, width=self.options.width, height=self.options.height, on_image=self._image
            )
        self.calibration: CalibrationSession | None = None
        self.recording: Any = None  # a StreamRecording (record.py) while one runs
        self.scripts = ScriptFolder(self.options.scripts_dir, service.validator.names)
        self._loop_stop = threading.Event()
        self._played_s = 0.0  # how long the last script played holds the head (its speech included)
        self._head_info = views.head_info(service, (self.options.width, self.options.height))

    # -- fan-out -----------------------------------------------------------------------------------
    def emit(self, message: dict[str, Any]) -> None:
        for listener in list(self.listeners):
            try:
                listener(message)
            except Exception:  # noqa: BLE001 - one broken socket must not silence the others
                pass

    def _image(self, image: TwinImage) -> None:
        for listener in list(self.image_listeners):
            try:
                listener(image)
            except Exception:  # noqa: BLE001
                pass

    def push_state(self) -> None:
        self.emit({"type": "state", **self.state()})

    def _manual_snapshot(self, snap: ChainSnapshot) -> None:
        self.emit({"type": "telemetry", **views.telemetry(snap, self.roles)})

    # -- reading -----------------------------------------------------------------------------------
    def head(self) -> dict[str, Any]:
        return self._head_info

    def state(self) -> dict[str, Any]:
        s = self.service.status()
        return {
            "t_s": round(s.t_s, 4),
            "running": s.running or self.service.paused,
            "estop_latched": s.estop_latched,
            "torque_on": s.torque_on,
            "hold": self.hold,
            "manual": self.lender.manual,
            "calibrating": self.calibration is not None and self.calibration.active,
            "clients": self.clients,
            "silent_clients": self.liveness.silent,
            "frames": s.frames,
            "late": s.late,
            "tracks": views.tracks(s),
            "verdict": views.verdict(self.service.last_trace),
            "last_drop_s": None if self.last_drop_s is None else round(self.last_drop_s, 4),
            "last_drop_reason": self.last_drop_reason,
            "render_error": self.renderer.error if self.renderer is not None else "rendering is off",
            "error": s.error,
        }

    def servos(self) -> dict[str, Any]:
        return views.telemetry(self.service.telemetry(), self.roles)

    # -- live --------------------------------------------------------------------------------------
    def _motion(self, fn: Callable[[], CommandHandle], field_name: str) -> dict[str, Any]:
        if self.lender.holding or (self.calibration is not None and self.calibration.active):
            raise ConflictError("the bus is lent (manual mode or a calibration): leave it first")
        try:
            return _command(fn())
        except EStopLatchedError as err:
            raise ConflictError(str(err)) from err
        except ServiceClosedError as err:
            raise ConflictError(str(err)) from err
        except ControllerError as err:
            if "torque is off" in str(err):
                raise ConflictError(str(err)) from err
            raise InvalidValueError(str(err), field=_field_of(str(err), field_name)) from err

    def set_aus(self, body: m.SetAus) -> dict[str, Any]:
        return self._motion(
            lambda: self.service.set_aus(body.aus, track="studio", transition_s=body.transition_s, merge=body.merge),
            "aus",
        )

    def clear_aus(self, body: m.ClearAus) -> dict[str, Any]:
        return self._motion(
            lambda: self.service.clear_aus(body.names, track="studio", transition_s=body.transition_s), "names"
        )

    def express(self, body: m.Express) -> dict[str, Any]:
        return self._motion(
            lambda: self.service.express(
                body.name,
                intensity=body.intensity,
                transition_s=body.transition_s,
                hold_s=body.hold_s,
                track=body.track,
            ),
            "name",
        )

    def gaze(self, body: m.Gaze) -> dict[str, Any]:
        if body.point_mm is not None and body.pad is not None:
            raise InvalidValueError("give one of point_mm or pad", field="pad")
        point = None if body.point_mm is None else (body.point_mm[0], body.point_mm[1], body.point_mm[2])
        if body.pad is not None:
            point = (body.pad[0] * PAD_ACROSS_MM, body.pad[1] * PAD_UP_MM, PAD_AHEAD_MM)
        return self._motion(lambda: self.service.look_at(point), "point_mm")

    def neutral(self, body: m.Neutral) -> dict[str, Any]:
        return self._motion(lambda: self.service.neutral(body.transition_s), "transition_s")

    def alive(self, body: m.Alive) -> dict[str, Any]:
        return self._motion(lambda: self.service.set_alive(blink=body.blink, idle=body.idle), "blink")

    def stop(self, body: m.Stop) -> dict[str, Any]:
        self._loop_stop.set()
        try:
            return _command(self.service.stop(body.track, release_s=body.release_s, hold=body.hold))
        except ServiceClosedError as err:
            raise ConflictError(str(err)) from err
        except ControllerError as err:
            raise InvalidValueError(str(err), field="track") from err

    def set_hold(self, body: m.Hold) -> dict[str, Any]:
        self.hold = body.hold
        self.push_state()
        return {"hold": self.hold}

    def estop(self, body: m.EStop) -> dict[str, Any]:
        """Never refused: the service latches and turns torque off; a lent bus is torqued off at once and
        a calibration aborted."""
        self._loop_stop.set()
        handle = self.service.estop(body.reason)
        self.lender.estop()
        if self.calibration is not None:
            self.calibration.abort()
        self.push_state()
        return _command(handle)

    def clear_estop(self, body: m.Empty) -> dict[str, Any]:
        try:
            handle = self.service.clear_estop()
        except ControllerError as err:
            raise ConflictError(str(err)) from err
        handle.wait(2.0)
        self.push_state()
        return _command(handle)

    def torque(self, body: m.OnOff) -> dict[str, Any]:
        if self.lender.holding:
            raise ConflictError("the bus is lent (manual mode or a calibration): use the per-servo torque")
        try:
            handle = self.service.torque_on() if body.on else self.service.torque_off()
        except ControllerError as err:
            raise ConflictError(str(err)) from err
        handle.wait(2.0)
        self.push_state()
        return _command(handle)

    # -- browsers ----------------------------------------------------------------------------------
    @property
    def clients(self) -> int:
        return self.liveness.connected

    def client_joined(self) -> int:
        """A WebSocket opened; its key for :meth:`client_heard` / :meth:`client_left`."""
        key = self.liveness.joined()
        self.push_state()
        return key

    def client_heard(self, key: int, *, heartbeat: bool = False, busy: int = 0) -> None:
        self.liveness.heard(key, heartbeat=heartbeat, busy=busy)

    def client_left(self, key: int) -> None:
        self.liveness.left(key)
        self.push_state()

    def _last_browser_gone(self, reason: str) -> None:
        """The last live browser closed or went silent (:mod:`.liveness`): ease to neutral (unless hold),
        manual mode ends; torque stays as it is."""
        self.last_drop_s = self.service.now_s()
        self.last_drop_reason = reason
        if not self.hold:
            self._loop_stop.set()
            if self.lender.manual:
                try:
                    self.lender.set_manual(False)
                except StudioError:
                    pass
            try:
                self.service.neutral(DROP_NEUTRAL_S)
            except ControllerError:
                pass  # e-stop latched / torque off / stopped: nothing is moving anyway
        self.push_state()

    def twin_png(self, which: str) -> TwinImage:
        if which not in ("achievable", "target"):
            raise NotFoundError(f"no twin image {which!r}; expected achievable or target", field="which")
        if self.renderer is None:
            raise ConflictError("rendering is off in this studio")
        image = self.renderer.latest_png(which)
        if image is None:
            raise ConflictError("no frame has run yet")
        trace = self.service.last_trace
        if trace is not None and image.frame_index != trace.index:
            image = self.renderer.call(lambda r: r._render(trace, which))
        return image

    # -- servos ------------------------------------------------------------------------------------
    def _servo_id(self, servo_id: int) -> int:
        if servo_id not in self.roles:
            raise NotFoundError(f"no servo with id {servo_id}; the head has {sorted(self.roles)}", field="id")
        return servo_id

    def _no_calibration(self) -> None:
        if self.calibration is not None and self.calibration.active:
            raise ConflictError("a calibration session holds the bus; finish or abort it first")

    def set_manual(self, body: m.OnOff) -> dict[str, Any]:
        self._no_calibration()
        self._loop_stop.set()
        self.lender.set_manual(body.on)
        self.push_state()
        return {"manual": self.lender.manual}

    def jog(self, servo_id: int, body: m.Jog) -> dict[str, Any]:
        sid = self._servo_id(servo_id)
        self._no_calibration()
        if (body.delta_tick is None) == (body.goal_tick is None):
            raise InvalidValueError("give exactly one of delta_tick or goal_tick", field="delta_tick")
        if not self.lender.manual:
            raise ConflictError('jog needs manual mode (POST /api/servos/manual {"on": true})')
        if self.service.estop_latched:
            raise ConflictError("the e-stop is latched")
        lo, hi = self.service.pipeline.calibration.position_limits_tick()[sid]

        def job(driver: Driver) -> dict[str, Any]:
            snap = driver.read_state()
            state = snap.servos[sid]
            base = state.goal_tick if state.goal_tick is not None else state.position_tick
            if base is None:
                raise ConflictError(f"servo {sid} has not reported a position yet")
            goal = body.goal_tick if body.goal_tick is not None else int(base) + int(body.delta_tick or 0)
            field_name = "goal_tick" if body.goal_tick is not None else "delta_tick"
            if not lo <= goal <= hi:
                raise InvalidValueError(
                    f"{field_name}: goal {goal} is outside servo {sid}'s calibrated limits {lo}..{hi}", field=field_name
                )
            if abs(goal - int(base)) > MAX_JOG_STEP_TICK:
                raise InvalidValueError(
                    f"{field_name}: goal {goal} is {goal - int(base):+d} ticks from the last goal {base}; one move is "
                    f"at most {MAX_JOG_STEP_TICK} ticks",
                    field=field_name,
                )
            if not state.torque_on:
                raise ConflictError(f"servo {sid}: torque is off; switch it on first")
            snap = driver.cycle({sid: goal})
            return {"id": sid, "goal_tick": goal, "position_tick": snap.servos[sid].position_tick}

        return dict(self._bus(job))

    def servo_torque(self, servo_id: int, body: m.OnOff) -> dict[str, Any]:
        sid = self._servo_id(servo_id)
        self._no_calibration()
        if body.on and self.service.estop_latched:
            raise ConflictError("the e-stop is latched; clear it first")

        def job(driver: Driver) -> dict[str, Any]:
            if body.on:
                driver.torque_on([sid])
                failed: tuple[int, ...] = ()
            else:
                failed = driver.torque_off([sid])
            driver.read_state()
            return {"id": sid, "torque_on": body.on, "unreached": list(failed)}

        return dict(self._bus(job))

    def reboot(self, servo_id: int, body: m.Empty) -> dict[str, Any]:
        sid = self._servo_id(servo_id)
        self._no_calibration()

        def job(driver: Driver) -> dict[str, Any]:
            driver.clear_fault(sid)
            driver.read_state()  # the driver reboots it and brings it back over its next cycles
            return {"id": sid, "rebooting": True}

        return dict(self._bus(job))

    def _bus(self, job: Callable[[Driver], Any]) -> Any:
        try:
            return self.lender.run(job)
        except HardwareError as err:
            raise ConflictError(f"bus: {err}") from err

    # -- record a live stream ------------------------------------------------------------------------
    def record_start(self, body: m.RecordStart) -> dict[str, Any]:
        from servoface.controller.studio.record import open_recording

        with self._lock:
            if self.recording is not None:
                raise ConflictError("a stream recording is running; stop it first")
            rec = open_recording(self.service.head, body.transport, body.port, body.tolerance)
            self.recording = rec
        if body.follow:
            try:
                rec.follow = self._motion(lambda: self.service.follow(rec.source, track="stream"), "follow")
            except StudioError:
                rec.follow = None  # e-stop latched / torque off / bus lent: record without moving the head
        self.push_state()
        return rec.state()

    def record_state(self) -> dict[str, Any]:
        rec = self.recording
        return rec.state() if rec is not None else {"active": False}

    def record_stop(self, body: m.Empty) -> dict[str, Any]:
        with self._lock:
            rec, self.recording = self.recording, None
        if rec is None:
            raise ConflictError("no stream recording is running")
        rec.close()
        if rec.follow is not None:
            try:
                self.service.stop("stream", release_s=0.3)
            except ControllerError:
                pass
        self.push_state()
        return {**rec.keys(), "messages": rec.source.stats.messages, "bad": rec.source.stats.bad, "over": rec.over}

    # -- calibrate ---------------------------------------------------------------------------------
    def calibrate_start(self, body: m.CalibrateStart) -> dict[str, Any]:
        if self.calibration is not None and self.calibration.active:
            raise ConflictError("a calibration session is already running")
        if self.service.estop_latched:
            raise ConflictError("the e-stop is latched; clear it first")
        if self.lender.manual:
            raise ConflictError("leave manual mode first")
        session = CalibrationSession(
            self.service.head,
            self.lender,
            body,
            self.options.out_dir,
            torque_wanted=lambda: self.service.status().torque_on,
            on_change=self._calibration_changed,
            on_saved=self._put_in_service,
        )
        self.calibration = session
        session.start()
        session.operator.wait_next(0, lambda: session.done)
        self.push_state()
        return session.state()

    def _put_in_service(self, calibration: Any, driver: Driver) -> None:
        """A calibration saved by a session (lender thread, loop paused): in service from the next frame."""
        from servoface.controller.studio import live_calibration

        prepared = live_calibration.prepare(self.service, calibration)
        live_calibration.install(self.service, prepared, driver, lambda: self.service.status().torque_on)
        self._calibration_installed()

    def _calibration_installed(self) -> None:
        self._head_info = views.head_info(self.service, (self.options.width, self.options.height))
        renderer = self.renderer
        if renderer is not None:  # seconds (the twin's tables): never while the loop waits
            cal = self.service.pipeline.calibration
            threading.Thread(target=renderer.set_calibration, args=(cal,), name="studio-twin-cal", daemon=True).start()

    def calibration_apply(self, body: m.CalibrationApply) -> dict[str, Any]:
        """A calibration file of ``--out-dir`` into service now: the gate built while the loop runs, then
        swapped in between two frames (:mod:`.live_calibration`)."""
        from servoface.calibration import load_calibration
        from servoface.calibration.errors import CalibrationError
        from servoface.controller.studio import live_calibration
        from servoface.controller.studio.calibrate import OUT_RE
        from servoface.hardware.errors import HardwareConfigError
        from servoface.sim.errors import SimError

        if not OUT_RE.fullmatch(body.file) or ".." in body.file:
            raise InvalidValueError(f"file: expected a bare file name ending in .json, got {body.file!r}", field="file")
        self._no_calibration()
        if self.lender.manual:
            raise ConflictError("leave manual mode first")
        path = Path(self.options.out_dir) / body.file
        if not path.is_file():
            raise NotFoundError(f"file: no calibration {body.file!r} in the studio's out dir", field="file")
        try:
            prepared = live_calibration.prepare(self.service, load_calibration(path))
        except (CalibrationError, ControllerError, SimError, HardwareConfigError, ValueError) as err:
            raise InvalidValueError(f"file: {err}", field="file") from err
        torque = self.service.status().torque_on
        self._bus(lambda driver: live_calibration.install(self.service, prepared, driver, lambda: torque))
        self._calibration_installed()
        self.push_state()
        return {"applied": str(path.resolve()), "servos": self._head_info["servos"]}

    def _calibration_changed(self) -> None:
        if self.calibration is not None:
            self.emit({"type": "calibrate", **self.calibration.state()})

    def calibrate_state(self) -> dict[str, Any]:
        return self.calibration.state() if self.calibration is not None else idle_state()

    def calibrate_reply(self, body: m.CalibrateReply) -> dict[str, Any]:
        if self.calibration is None:
            raise ConflictError("no calibration session; start one first")
        self.calibration.reply(body)
        if self.calibration.done:
            self.push_state()
        return self.calibration.state()

    def calibrate_plot(self, role: str) -> bytes:
        if self.calibration is None:
            raise NotFoundError("no calibration session", field="role")
        return self.calibration.plot_png(role)

    def calibrate_twin(self) -> bytes:
        if self.renderer is None:
            raise ConflictError("rendering is off in this studio")
        session = self.calibration
        prompt = session.operator.prompt if session is not None else None
        if prompt is None or prompt.target is None:
            raise ConflictError("no calibration prompt with a target to show")
        return self.renderer.render_targets_png({prompt.role: float(prompt.target)})

    # -- author ------------------------------------------------------------------------------------
    def _script(self, body: m.ScriptBody) -> tuple[Any, dict[str, Any], str]:
        text, field_name = text_of(body.document, body.toml)
        script = build(text, source="<studio>", allowed=self.service.validator.names, field=field_name)
        if script.face_type != self.service.head.face_type:
            raise InvalidValueError(
                f"{field_name}.script.face: the script is for a {script.face_type} face; this head is "
                f"{self.service.head.face_type}",
                field=f"{field_name}.script.face",
            )
        return script, toml_to_document(text), text

    def script_list(self) -> dict[str, Any]:
        from servoface.controller.shipped import shipped_scripts

        return {"scripts": self.scripts.names(), "shipped": sorted(shipped_scripts())}

    def script_load(self, name: str) -> dict[str, Any]:
        return self.scripts.load(name)

    def script_save(self, name: str, body: m.ScriptBody) -> dict[str, Any]:
        text, field_name = text_of(body.document, body.toml)
        self._script(body)
        return self.scripts.save(name, text, field_name)

    def script_check(self, body: m.ScriptBody) -> dict[str, Any]:
        script, document, text = self._script(body)
        return {"summary": summary(script, document), "toml": text}

    def script_sample(self, body: m.ScriptSample) -> dict[str, Any]:
        script, _, _ = self._script(body)
        return sample(script, body.fps)

    def script_preview(self, body: m.ScriptPreview) -> bytes:
        if self.renderer is None:
            raise ConflictError("rendering is off in this studio")
        script, _, _ = self._script(body)
        aus = script.timeline.sample_aus(min(body.t_s, float(script.end_s)))
        return self.renderer.render_aus_png(aus, body.which)

    def play(self, body: m.Play) -> dict[str, Any]:
        given = sum(x is not None for x in (body.document, body.toml, body.name))
        if given != 1:
            raise InvalidValueError("give exactly one of document, toml or name", field="name")
        if body.name is not None:
            loaded = self.scripts.load(body.name)
            script, _, _ = self._script(m.ScriptBody(toml=loaded["toml"]))
        else:
            script, _, _ = self._script(body)
        if body.track not in self.service.tracks.slots:
            raise InvalidValueError(f"track: expected one of {list(self.service.tracks.slots)}", field="track")
        result = self._motion(lambda: self._play_script(script, body.track), "document")
        if body.loop:
            self._start_loop(script, body.track, result)
        return result

    def _play_script(self, script: Any, track: str) -> CommandHandle:
        """Play a script on ``track``; one with say cues or a sound file (beside the scripts folder's files)
        is spoken as everywhere (:func:`~servoface.controller.speech.script_play.submit_script_speaking`: the
        speech track, the head's jaw budget, the sound on this machine's output)."""
        from servoface.controller.speech.script_play import speaks, submit_script_speaking

        self._played_s = float(script.end_s)
        if not speaks(script):
            return self.service.play(script, track=track)
        handle, run = submit_script_speaking(self.service, script, track=track, audio_dir=self.options.scripts_dir)
        self._played_s = run.total_s  # its speech may end after the script: a loop waits for it
        return handle

    def _start_loop(self, script: Any, track: str, first: dict[str, Any]) -> None:
        self._loop_stop.set()
        stop = self._loop_stop = threading.Event()

        def again() -> None:
            while not stop.is_set():
                end = self.service.now_s() + max(float(script.end_s), self._played_s)
                while not stop.is_set() and self.service.now_s() < end:
                    stop.wait(0.05)
                if stop.is_set():
                    return
                try:
                    self._play_script(script, track)
                except ControllerError:
                    return

        threading.Thread(target=again, name="studio-loop-play", daemon=True).start()

    # -- life --------------------------------------------------------------------------------------
    def close(self) -> None:
        self._loop_stop.set()
        self.liveness.close()
        if self.recording is not None:
            self.recording.close()
        if self.calibration is not None:
            self.calibration.abort()
        self.lender.close()
        if self.renderer is not None:
            self.renderer.close()
