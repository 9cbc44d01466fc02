"""Calibrating from the browser: the same procedure `servoface calibrate` runs
(:func:`servoface.calibration.procedure.run_procedure`: the same steps, the same safe window for jogs and
go-tos, the same fit, checks and file), with an :class:`Operator` whose answers come over HTTP.

The procedure runs on the studio's bus lender (the service loop is paused for the session; the Bus
Watchdog is disarmed, since a person takes minutes per point). ``ask`` publishes the prompt and waits for a
reply, refreshing the servo's present position every 0.25 s so the page shows it move. At the end the
driver is re-configured from the running calibration (its servo-side limits restored), torque comes back
as it was, and the loop resumes. An e-stop or ``abort`` ends the session with nothing saved."""

from __future__ import annotations

import dataclasses
import queue
import re
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from servoface.calibration.procedure import Abort, Capture, Finish, GoTo, Jog, Prompt, Relax, Reply
from servoface.controller.studio.errors import ConflictError, InvalidValueError, NotFoundError
from servoface.controller.studio.lender import BusLender
from servoface.controller.studio.models import CalibrateReply, CalibrateStart
from servoface.hardware.driver import Driver
from servoface.sim.head import Head

OUT_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,95}\.json$")
REFRESH_S = 0.25
MAX_MESSAGES = 50


class _Closed(Exception):
    """The session was ended from outside while the procedure waited."""


class WebOperator:
    """The operator of :mod:`servoface.calibration.procedure`, answered by :meth:`reply`."""

    def __init__(self, on_change: Callable[[], None]) -> None:
        self.on_change = on_change
        self.access: Any = None  # set on the lender thread: present-tick refreshes use it
        self.prompt: Prompt | None = None
        self.messages: list[str] = []
        self.captured: list[dict[str, Any]] = []
        self.asked = 0
        self._replies: queue.Queue[Reply] = queue.Queue()
        self._cond = threading.Condition()
        self._capturing: dict[str, Any] | None = None

    # -- the procedure's side (lender thread) ------------------------------------------------------
    def ask(self, prompt: Prompt) -> Reply:
        with self._cond:
            self.prompt = prompt
            self.asked += 1
            self._cond.notify_all()
        self.on_change()
        while True:
            try:
                reply = self._replies.get(timeout=REFRESH_S)
            except queue.Empty:
                self._refresh()
                continue
            if isinstance(reply, Capture) and (reply.target is not None or prompt.target is not None):
                target = reply.target if reply.target is not None else prompt.target
                self._capturing = {"role": prompt.role, "step": prompt.step, "target": target}
            return reply

    def tell(self, message: str) -> None:
        with self._cond:
            self.messages = (self.messages + [message])[-MAX_MESSAGES:]
        self.on_change()

    def read_present(self, servo_id: int, tick: int) -> None:
        """Called by the access wrapper: the first read after a capture is the captured tick."""
        if self._capturing is not None:
            self.captured.append({**self._capturing, "tick": int(tick)})
            self._capturing = None

    def _refresh(self) -> None:
        prompt = self.prompt
        if prompt is None or self.access is None:
            return
        try:
            tick = int(self.access.inner.read_present_tick(prompt.servo_id))
        except Exception:  # noqa: BLE001 - a missed refresh is shown next time
            return
        if tick != prompt.present_tick:
            self.prompt = dataclasses.replace(prompt, present_tick=tick)
            self.on_change()

    # -- the browser's side ------------------------------------------------------------------------
    def put(self, reply: Reply) -> int:
        with self._cond:
            asked = self.asked
        self._replies.put(reply)
        return asked

    def wait_next(self, asked: int, done: Callable[[], bool], timeout_s: float = 10.0) -> None:
        with self._cond:
            self._cond.wait_for(lambda: self.asked > asked or done(), timeout_s)

    def wake(self) -> None:
        with self._cond:
            self._cond.notify_all()


class _RecordingAccess:
    """The CLI's bus access, noting each present-position read for the captured list."""

    def __init__(self, inner: Any, operator: WebOperator) -> None:
        self.inner = inner
        self.operator = operator

    def read_present_tick(self, servo_id: int) -> int:
        tick = int(self.inner.read_present_tick(servo_id))
        self.operator.read_present(servo_id, tick)
        return tick

    def set_torque(self, servo_id: int, enabled: bool) -> None:
        self.inner.set_torque(servo_id, enabled)

    def write_goal_tick(self, servo_id: int, tick: int) -> None:
        self.inner.write_goal_tick(servo_id, tick)

    def set_position_limits(self, servo_id: int, min_tick: int, max_tick: int) -> None:
        self.inner.set_position_limits(servo_id, min_tick, max_tick)

    def read_position_limits(self, servo_id: int) -> tuple[int, int]:
        lo, hi = self.inner.read_position_limits(servo_id)
        return int(lo), int(hi)


class CalibrationSession:
    """One calibration run from the browser (see the module docstring)."""

    def __init__(
        self,
        head: Head,
        lender: BusLender,
        request: CalibrateStart,
        out_dir: Path,
        *,
        torque_wanted: Callable[[], bool],
        on_change: Callable[[], None],
        on_saved: Callable[[Any, Driver], None] | None = None,
    ) -> None:
        """``on_saved(calibration, driver)``: on the lender thread (loop paused) once the file is written,
        to put the new calibration into service (:mod:`.live_calibration`); it re-configures the driver
        and brings torque back itself. Without it the running calibration's limits are restored."""
        from servoface.controller.calibration_specs import specs_from_head

        self.head = head
        self.lender = lender
        self.on_change = on_change
        self.torque_wanted = torque_wanted
        self.on_saved = on_saved
        all_specs = specs_from_head(head)
        known = [s.role for s in all_specs]
        if request.roles is not None:
            unknown = [r for r in request.roles if r not in known]
            if unknown or not request.roles:
                raise InvalidValueError(f"roles: unknown role(s) {unknown}; the head has {known}", field="roles")
            self.specs = [s for s in all_specs if s.role in request.roles]
        else:
            self.specs = all_specs
        name = request.out or f"calibration-{head.name}.json"
        if not OUT_RE.fullmatch(name) or ".." in name:
            raise InvalidValueError(f"out: expected a bare file name ending in .json, got {name!r}", field="out")
        self.out = Path(out_dir) / name
        self.request = request
        self.operator = WebOperator(self._changed)
        self.plot_dir = Path(tempfile.mkdtemp(prefix="servoface-studio-plots-"))
        self.done = False
        self.error = ""
        self.result: dict[str, Any] | None = None
        self._thread = threading.Thread(target=self._run, name="studio-calibration", daemon=True)

    def start(self) -> None:
        self._thread.start()

    @property
    def active(self) -> bool:
        return not self.done

    def _changed(self) -> None:
        self.on_change()

    # -- the procedure (on the lender thread) ------------------------------------------------------
    def _run(self) -> None:
        try:
            self.lender.run(self._job, timeout_s=24 * 3600.0)
        except BaseException as err:  # noqa: BLE001 - reported to the page
            self.error = _describe(err)
        finally:
            self.done = True
            self.operator.prompt = None
            self.operator.wake()
            self._changed()

    def _job(self, driver: Driver) -> None:
        from servoface.calibration.errors import CalibrationError
        from servoface.calibration.fileformat import load_calibration, save_calibration
        from servoface.calibration.procedure import ProcedureOptions, run_procedure
        from servoface.controller.cli.calibrate import BusServoAccess, check_servos_answer

        keep = guide = None
        existing = self.head.calibration_path
        if existing is not None and Path(existing).exists():
            try:
                guide = load_calibration(existing)
            except CalibrationError:
                guide = None
            keep = guide if self.request.roles is not None else None
        options = ProcedureOptions(
            intermediate=self.request.points,
            free_points=self.request.free_points,
            curve_kind=self.request.curve,
            guide=guide,
        )
        driver.disarm_watchdog()
        installed = False
        access = _RecordingAccess(BusServoAccess(driver.bus), self.operator)
        self.operator.access = access
        try:
            check_servos_answer(driver.bus, self.specs)
            result = run_procedure(
                access, self.operator, self.specs, self.head.name, options=options, plot_dir=self.plot_dir, keep=keep
            )
            result.saved_to = save_calibration(result.calibration, self.out)
            self.result = {
                "saved_to": str(Path(result.saved_to).resolve()),
                "servos": [
                    {
                        "role": role,
                        "kind": r.servo.curve.kind,
                        "min_tick": r.servo.min_tick,
                        "max_tick": r.servo.max_tick,
                        "neutral_tick": r.servo.neutral_tick,
                        "max_residual_tick": round(float(r.max_residual_tick), 3),
                    }
                    for role, r in result.reports.items()
                ],
                "warnings": list(result.warnings),
                "plots": sorted(result.plots),
                "applied": False,
            }
            if self.request.apply and self.on_saved is not None:
                self.on_saved(result.calibration, driver)  # the new limits written, torque back as it was
                installed = True
                self.result["applied"] = True
        finally:
            if not installed:
                driver.configure()  # the running calibration's servo-side limits back, torque off
                if self.torque_wanted():
                    driver.torque_on()  # goals pinned to where the servos are

    # -- the browser's side ------------------------------------------------------------------------
    def reply(self, body: CalibrateReply) -> None:
        if self.done:
            raise ConflictError("the calibration session has ended; start a new one")
        prompt = self.operator.prompt
        if prompt is None:
            raise ConflictError("the calibration is not waiting for an answer yet; try again")
        reply: Reply
        if body.action == "capture":
            reply = Capture(body.target)
        elif body.action == "jog":
            if body.delta_tick is None:
                raise InvalidValueError("delta_tick: required for a jog (whole ticks)", field="delta_tick")
            reply = Jog(body.delta_tick)
        elif body.action == "goto":
            if body.tick is None:
                raise InvalidValueError("tick: required for a goto (0..4095)", field="tick")
            reply = GoTo(body.tick)
        elif body.action == "goto_suggested":
            if prompt.suggested_tick is None:
                raise ConflictError("no earlier calibration of this servo to go by; jog instead")
            reply = GoTo(prompt.suggested_tick)
        elif body.action == "relax":
            reply = Relax()
        elif body.action == "finish":
            reply = Finish()
        else:
            reply = Abort()
        asked = self.operator.put(reply)
        self.operator.wait_next(asked, lambda: self.done)

    def abort(self) -> None:
        """From any thread (an e-stop): the procedure ends at its next question, nothing saved."""
        if not self.done:
            self.operator.put(Abort())

    def plot_png(self, role: str) -> bytes:
        if not re.fullmatch(r"[A-Za-z0-9_]{1,64}", role):
            raise InvalidValueError(f"role: expected a servo role, got {role!r}", field="role")
        p = self.plot_dir / f"{role}.png"
        if not p.is_file():
            raise NotFoundError(f"no curve plot for {role!r} (not calibrated in this session yet)", field="role")
        return p.read_bytes()

    def state(self) -> dict[str, Any]:
        p = self.operator.prompt
        prompt = None
        if p is not None and not self.done:
            prompt = {
                "role": p.role,
                "servo_id": p.servo_id,
                "unit": p.unit,
                "step": p.step,
                "target": p.target,
                "present_tick": p.present_tick,
                "text": p.text,
                "suggested_tick": p.suggested_tick,
            }
        return {
            "active": not self.done,
            "done": self.done,
            "error": self.error,
            "out": str(self.out.resolve()),
            "prompt": prompt,
            "captured": list(self.operator.captured),
            "messages": list(self.operator.messages),
            "result": self.result,
        }


def idle_state() -> dict[str, Any]:
    return {
        "active": False,
        "done": False,
        "error": "",
        "out": "",
        "prompt": None,
        "captured": [],
        "messages": [],
        "result": None,
    }


def _describe(err: BaseException) -> str:
    from servoface.calibration.errors import ProcedureAborted

    if isinstance(err, ProcedureAborted):
        return f"{err}; nothing saved"
    return f"{type(err).__name__}: {err}"
