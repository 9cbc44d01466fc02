"""The calibration procedure: capture points on the real (or emulated) head, fit, check, plot, save.

The procedure never imports the driver. Its caller hands it two small things:

- a :class:`ServoAccess` (read present tick, torque on/off, write goal tick for one servo), which the
  controller adapts from the hardware bus;
- an :class:`Operator`, the person at the head: the CLI asks through ``input()``, a test scripts it.

Per servo: torque off; the operator moves the servo by hand (or jogs it: the first jog pins the goal
to the present position, then switches torque on) to its neutral, lower and upper targets and to any
intermediate targets, and confirms each; the present tick is captured. Then the points are fitted,
checked (monotone, coverage, residuals, tick range), plotted and, at the end, saved atomically.
A capture that fails the checks is reported to the operator and the servo is measured again. Once both
ends are captured the servo's Min/Max Position Limit are narrowed to them (`PositionLimits`, when the access
offers it); a re-measure first puts back the limits the servo had, and a run that ends without saving
(aborted, failed, interrupted) puts back every servo's it narrowed.
"""

from __future__ import annotations

import math
import os
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Protocol

import numpy as np
from servoface.calibration.errors import (
    CalibrationError,
    MeasurementCsvError,
    ProcedureAborted,
    ProcedureError,
)
from servoface.calibration.fileformat import metadata_now, save_calibration
from servoface.calibration.fitting import FitReport, far_outside, fit_coupled_servo, fit_servo
from servoface.calibration.head import HeadCalibration
from servoface.calibration.measurements import Measurement, read_measurements_csv
from servoface.calibration.plot import plot_servo
from servoface.calibration.servo import MAX_POSITION_TICK, MIN_POSITION_TICK
from servoface.calibration.spec import ServoSpec

Step = Literal["neutral", "lower", "upper", "point", "extra"]


class ServoAccess(Protocol):
    """What the procedure needs from the bus, one servo at a time (ids, not roles)."""

    def read_present_tick(self, servo_id: int) -> int: ...

    def set_torque(self, servo_id: int, enabled: bool) -> None: ...

    def write_goal_tick(self, servo_id: int, tick: int) -> None: ...


@dataclass(frozen=True)
class Prompt:
    """One question to the operator. ``target`` is the value to move to, or None: "enter what you set"."""

    role: str
    servo_id: int
    unit: str
    step: Step
    target: float | None
    present_tick: int
    text: str
    suggested_tick: int | None = None  # where an earlier calibration puts ``target`` (a jog hint)


@dataclass(frozen=True)
class Capture:
    """Take the present position as this step's point; ``target`` overrides the asked-for value."""

    target: float | None = None


@dataclass(frozen=True)
class Jog:
    """Move the servo by ``delta_tick`` under torque (pins the goal to the present tick first)."""

    delta_tick: int


@dataclass(frozen=True)
class GoTo:
    """Move the servo to ``tick`` under torque (pins the goal to the present tick first)."""

    tick: int


@dataclass(frozen=True)
class Relax:
    """Switch torque off again (after jogging) so the servo can be moved by hand."""


@dataclass(frozen=True)
class Finish:
    """No (more) points for this step: ends the free-point loop, or skips an intermediate point."""


@dataclass(frozen=True)
class Abort:
    """Stop the whole procedure; nothing is saved."""


Reply = Capture | Jog | GoTo | Relax | Finish | Abort


class Operator(Protocol):
    """The person at the head (or a script standing in for one)."""

    def ask(self, prompt: Prompt) -> Reply: ...

    def tell(self, message: str) -> None: ...


@dataclass
class ProcedureResult:
    """What a calibration run produced."""

    calibration: HeadCalibration
    reports: dict[str, FitReport] = field(default_factory=dict)
    plots: dict[str, Path] = field(default_factory=dict)
    saved_to: Path | None = None

    @property
    def warnings(self) -> list[str]:
        return [w for r in self.reports.values() for w in r.warnings]


@dataclass(frozen=True)
class ProcedureOptions:
    """``intermediate``: known targets asked for between the ends; ``free_points``: then let the operator
    add points whose target they enter; ``curve_kind``: one kind for all, a per-role mapping, or None
    (linear for joints, pchip for anchors); ``attempts``: re-measures allowed per servo; ``max_jogs``
    bounds one step's conversation (a safety net against a stuck script); ``guide``: an earlier
    calibration whose ticks are offered as ``Prompt.suggested_tick`` (the CLI's "g" key jogs there)."""

    intermediate: int = 3
    free_points: bool = False
    curve_kind: str | Mapping[str, str] | None = None
    attempts: int = 3
    max_jogs: int = 500
    guide: HeadCalibration | None = None
    max_step_tick: int = 300  # one jog or go-to moves at most this far from the present position (~26 deg)
    window_margin_tick: int = 40  # slack around the declared range before the limits are captured
    unknown_window_tick: int = 600  # +-window around the start when the range in ticks is not known


class PositionLimits(Protocol):
    """Optional on a `ServoAccess`: write the captured limits to the servo's Min/Max Position Limit, and
    read the limits in force (so that a re-measure or a run that saves nothing puts them back)."""

    def set_position_limits(self, servo_id: int, min_tick: int, max_tick: int) -> None: ...

    def read_position_limits(self, servo_id: int) -> tuple[int, int]: ...


def _kind_for(options: ProcedureOptions, role: str) -> str | None:
    if isinstance(options.curve_kind, Mapping):
        return options.curve_kind.get(role)
    return options.curve_kind


def _plan(spec: ServoSpec, intermediate: int) -> list[tuple[Step, float]]:
    steps: list[tuple[Step, float]] = [("neutral", spec.neutral)]
    for step, value in (("lower", spec.lower), ("upper", spec.upper)):
        if value != spec.neutral:
            steps.append((step, value))  # type: ignore[arg-type]
    used = {v for _, v in steps}
    for v in np.linspace(spec.lower, spec.upper, intermediate + 2)[1:-1]:
        if float(v) not in used:
            steps.append(("point", float(v)))
    return steps


class _Session:
    def __init__(self, access: ServoAccess, operator: Operator, options: ProcedureOptions) -> None:
        self.access = access
        self.operator = operator
        self.options = options
        self.torque_on = False
        self.goal: int | None = None  # last goal written while torque is on
        self.window: tuple[int, int] = (MIN_POSITION_TICK, MAX_POSITION_TICK)  # where goals may go
        self.window_why = ""
        # Min/Max Position Limit each servo had before this run narrowed it (None: not readable), in the
        # order narrowed: a re-measure puts them back first, and so does a run that ends without saving
        self.narrowed: dict[int, tuple[str, tuple[int, int] | None]] = {}

    def open_window(self, spec: ServoSpec) -> None:
        """Before the limits are captured: the declared range (through an earlier calibration of this servo,
        else the joint's span in degrees, else a fixed window) around where the servo is now, widened by
        a margin. Goals outside it are refused, never written."""
        opts = self.options
        start = self.present(spec)
        guide = opts.guide
        if guide is not None and spec.role in guide and guide[spec.role].servo_id == spec.servo_id:
            g = guide[spec.role]
            lo, hi = g.min_tick - opts.window_margin_tick, g.max_tick + opts.window_margin_tick
            why = f"the earlier calibration's {g.min_tick}..{g.max_tick} + {opts.window_margin_tick} ticks"
        elif spec.kind == "joint":
            span = int(math.ceil((spec.upper - spec.lower) * 4096 / 360)) + opts.window_margin_tick
            lo, hi = start - span, start + span
            why = f"the declared {spec.lower:g}..{spec.upper:g} deg around where the servo stood ({start})"
        else:
            lo, hi = start - opts.unknown_window_tick, start + opts.unknown_window_tick
            why = f"+-{opts.unknown_window_tick} ticks around where the servo stood ({start})"
        self.window = (max(MIN_POSITION_TICK, lo), min(MAX_POSITION_TICK, hi))
        self.window_why = why

    def narrow_window(self, spec: ServoSpec, lo: int, hi: int) -> None:
        """Lower and upper captured: goals stay between them, and the servo's own limits say so too."""
        lo, hi = min(lo, hi), max(lo, hi)
        self.window = (lo, hi)
        self.window_why = f"the captured limits {lo}..{hi}"
        setter = getattr(self.access, "set_position_limits", None)
        if setter is not None:
            self.torque_off(spec)  # EEPROM: written with torque off
            if spec.servo_id not in self.narrowed:
                reader = getattr(self.access, "read_position_limits", None)
                before = None if reader is None else tuple(int(t) for t in reader(spec.servo_id))
                self.narrowed[spec.servo_id] = (spec.role, None if before is None else (before[0], before[1]))
            setter(spec.servo_id, lo, hi)
            self.operator.tell(f"'{spec.role}': Min/Max Position Limit set to {lo}..{hi} before the other points")

    def widen_back(self, spec: ServoSpec) -> None:
        """Before a servo is measured again: its Min/Max Position Limit as they were before this run narrowed
        them to the captures that failed (a re-measure may need ticks past those), or, where they could not
        be read, the safe window of the new attempt. Torque off first (EEPROM)."""
        entry = self.narrowed.pop(spec.servo_id, None)
        if entry is None:
            return
        _, before = entry
        lo, hi = before if before is not None else self.window
        self.torque_off(spec)
        self.access.set_position_limits(spec.servo_id, lo, hi)  # type: ignore[attr-defined]
        if before is None:
            self.narrowed[spec.servo_id] = entry  # still not the servo's own limits: restored at the end too
        self.operator.tell(f"'{spec.role}': Min/Max Position Limit back to {lo}..{hi} for the new attempt")

    def restore_limits(self) -> None:
        """A run that saves nothing leaves each servo's Min/Max Position Limit as it found them (torque off;
        one attempt per servo, failures told to the operator, never raised over the error that ended the
        run)."""
        for servo_id, (role, before) in list(self.narrowed.items()):
            if before is None:
                self.operator.tell(
                    f"'{role}': Min/Max Position Limit left at this run's values (the servo's own could not be read)"
                )
                continue
            try:
                self.access.set_torque(servo_id, False)
                self.access.set_position_limits(servo_id, *before)  # type: ignore[attr-defined]
            except Exception as err:  # noqa: BLE001 (best effort while another error ends the run)
                self.operator.tell(
                    f"'{role}': could not put Min/Max Position Limit back to {before[0]}..{before[1]}: {err}"
                )
                continue
            del self.narrowed[servo_id]
            self.operator.tell(f"'{role}': Min/Max Position Limit back to {before[0]}..{before[1]} (nothing saved)")

    def refused(self, spec: ServoSpec, tick: int) -> str | None:
        """Why a goal of ``tick`` may not be written (None: it may)."""
        lo, hi = self.window
        if not lo <= tick <= hi:
            return f"outside the safe window {lo}..{hi} ({self.window_why})"
        present = self.present(spec)
        if abs(tick - present) > self.options.max_step_tick:
            return (
                f"{tick - present:+d} ticks from where the servo is ({present}); one move is at most "
                f"{self.options.max_step_tick} ticks (jog in steps)"
            )
        return None

    def present(self, spec: ServoSpec) -> int:
        tick = int(self.access.read_present_tick(spec.servo_id))
        if not MIN_POSITION_TICK <= tick <= MAX_POSITION_TICK:
            raise ProcedureError(
                f"servo '{spec.role}' (id {spec.servo_id}) reports position {tick}, outside "
                f"{MIN_POSITION_TICK}..{MAX_POSITION_TICK}: the horn is past the end of its turn (turn it "
                "back) or the servo is not in position control mode"
            )
        return tick

    def hint(self, spec: ServoSpec, target: float | None) -> int | None:
        """The tick an earlier calibration (``options.guide``) gives for ``target``, if it knows the servo."""
        guide = self.options.guide
        if guide is None or target is None or spec.role not in guide:
            return None
        servo = guide[spec.role]
        if servo.servo_id != spec.servo_id:
            return None
        tick = servo.curve.forward(target)
        return int(min(max(round(float(tick)), MIN_POSITION_TICK), MAX_POSITION_TICK))

    def torque_off(self, spec: ServoSpec) -> None:
        self.access.set_torque(spec.servo_id, False)
        self.torque_on = False
        self.goal = None

    def move_to(self, spec: ServoSpec, tick: int) -> None:
        """Goal ``tick`` under torque; the first move pins the goal to the present tick, then torque on.
        A goal outside the safe window, or too far from the present position, is refused with a message
        and nothing is written."""
        tick = int(tick)
        why = self.refused(spec, tick)
        if why is not None:
            self.operator.tell(f"'{spec.role}': move to {tick} refused: {why}")
            return
        if not self.torque_on or self.goal is None:
            present = self.present(spec)
            self.access.write_goal_tick(spec.servo_id, present)  # pin first: no jump on torque-on
            self.access.set_torque(spec.servo_id, True)
            self.torque_on, self.goal = True, present
        self.goal = tick
        self.access.write_goal_tick(spec.servo_id, self.goal)

    def jog(self, spec: ServoSpec, delta: int) -> None:
        """Jog from the last goal (not the lagging present position), so quick key presses add up."""
        if isinstance(delta, bool) or not isinstance(delta, int) or abs(delta) > MAX_POSITION_TICK:
            self.operator.tell(f"'{spec.role}': jog {delta!r} refused: expected whole ticks within one turn")
            return
        base = self.goal if self.torque_on and self.goal is not None else self.present(spec)
        self.move_to(spec, base + delta)

    def step(self, spec: ServoSpec, step: Step, target: float | None) -> Measurement | None:
        for _ in range(self.options.max_jogs):
            where = f"{target:g} {spec.unit}" if target is not None else "a pose of your choice"
            text = {
                "neutral": f"move '{spec.role}' to its NEUTRAL ({where})",
                "lower": f"move '{spec.role}' to its LOWER limit ({where})",
                "upper": f"move '{spec.role}' to its UPPER limit ({where})",
                "point": f"move '{spec.role}' to {where}",
                "extra": f"move '{spec.role}' to {where} and enter its target in {spec.unit}",
            }[step]
            present = self.present(spec)
            reply = self.operator.ask(
                Prompt(spec.role, spec.servo_id, spec.unit, step, target, present, text, self.hint(spec, target))
            )
            if isinstance(reply, Abort):
                raise ProcedureAborted(f"calibration aborted by the operator at servo '{spec.role}' ({step})")
            if isinstance(reply, Jog):
                self.jog(spec, reply.delta_tick)
                continue
            if isinstance(reply, GoTo):
                self.move_to(spec, reply.tick)
                continue
            if isinstance(reply, Relax):
                self.torque_off(spec)
                continue
            if isinstance(reply, Finish):
                if step in ("neutral", "lower", "upper"):
                    self.operator.tell(f"'{spec.role}': the {step} point is required")
                    continue
                return None
            value = reply.target if reply.target is not None else target
            if value is None or not np.isfinite(value):
                self.operator.tell(f"'{spec.role}': enter the target in {spec.unit} for this point")
                continue
            return Measurement(spec.role, float(value), self.present(spec))
        raise ProcedureError(f"servo '{spec.role}': no capture after {self.options.max_jogs} replies ({step})")

    def measure(self, spec: ServoSpec) -> list[Measurement]:
        self.torque_off(spec)
        self.open_window(spec)
        self.widen_back(spec)  # a re-measure: the limits the failed captures set are not the servo's
        points: list[Measurement] = []
        ends: list[int] = []
        plan = _plan(spec, self.options.intermediate)
        last_end = max(i for i, (step, _) in enumerate(plan) if step in ("neutral", "lower", "upper"))
        try:
            for i, (step, target) in enumerate(plan):
                m = self.step(spec, step, target)
                if m is not None:
                    points.append(m)
                    if step in ("neutral", "lower", "upper"):
                        ends.append(m.tick)
                if i == last_end and len(ends) >= 2:  # both ends known: the window shrinks to them
                    self.narrow_window(spec, min(ends), max(ends))
            while self.options.free_points:
                m = self.step(spec, "extra", None)
                if m is None:
                    break
                points.append(m)
        finally:
            self.torque_off(spec)
        return points


def run_procedure(
    access: ServoAccess,
    operator: Operator,
    specs: Sequence[ServoSpec],
    head: str,
    *,
    options: ProcedureOptions | None = None,
    plot_dir: str | os.PathLike[str] | None = None,
    out: str | os.PathLike[str] | None = None,
    keep: HeadCalibration | None = None,
) -> ProcedureResult:
    """Calibrate ``specs`` interactively. ``keep``: servos of an existing calibration that are not in
    ``specs`` are carried over unchanged. Saves to ``out`` (atomically) when given."""
    opts = options or ProcedureOptions()
    session = _Session(access, operator, opts)
    reports: dict[str, FitReport] = {}
    try:
        for spec in specs:
            for attempt in range(1, opts.attempts + 1):
                points = session.measure(spec)
                try:
                    reports[spec.role] = fit_servo(
                        spec, [(m.target, m.tick) for m in points], _kind_for(opts, spec.role)
                    )
                    break
                except CalibrationError as err:
                    operator.tell(f"{err} (attempt {attempt} of {opts.attempts})")
                    if attempt == opts.attempts:
                        raise ProcedureError(
                            f"servo '{spec.role}': no usable calibration after {attempt} attempts: {err}"
                        ) from err
            for w in reports[spec.role].warnings:
                operator.tell(w)
        return _finish(reports, specs, head, "procedure", "", plot_dir, out, keep)
    except BaseException:  # aborted, failed, interrupted: nothing saved, so the servos' limits go back
        session.restore_limits()
        raise


def calibrate_from_csv(
    csv_path: str | os.PathLike[str],
    specs: Sequence[ServoSpec],
    head: str,
    *,
    curve_kind: str | Mapping[str, str] | None = None,
    plot_dir: str | os.PathLike[str] | None = None,
    out: str | os.PathLike[str] | None = None,
    keep: HeadCalibration | None = None,
    skip_roles: Collection[str] = (),
) -> ProcedureResult:
    """Non-interactive mode: fit every servo in ``specs`` from a ``role,target,tick`` CSV.

    A role in ``specs`` with no rows is an error unless ``keep`` has it (then it is carried over). Rows
    with ``neighbour=tick`` cells make that servo a coupled anchor (RBF map, see
    :func:`servoface.calibration.fitting.fit_coupled_servo`); its neighbours must be plain servos. Rows of
    ``skip_roles`` (the head's other servos, not calibrated this time) are passed over.
    """
    own = {s.role for s in specs}
    skip = set(skip_roles) - own
    rows = read_measurements_csv(
        csv_path, roles=own, neighbour_roles=own | set(keep.roles if keep else ()), skip_roles=skip
    )
    opts = ProcedureOptions(curve_kind=curve_kind)
    reports: dict[str, FitReport] = {}
    missing = [s.role for s in specs if s.role not in rows and (keep is None or s.role not in keep)]
    if missing:
        raise ProcedureError(f"{csv_path}: no measurements for role(s) {missing}")
    for spec in specs:  # a target far outside the servo's range is a typo: named by its line, before any fit
        for m in rows.get(spec.role, ()):
            if (why := far_outside(spec, m.target)) is not None:
                raise MeasurementCsvError(str(csv_path), m.line, why)
    coupled = [s for s in specs if s.role in rows and rows[s.role][0].neighbours]
    for spec in specs:
        if spec.role not in rows or spec in coupled:
            continue
        try:
            reports[spec.role] = fit_servo(
                spec, [(m.target, m.tick) for m in rows[spec.role]], _kind_for(opts, spec.role)
            )
        except CalibrationError as err:
            lines = ", ".join(str(m.line) for m in rows[spec.role])
            raise type(err)(f"{csv_path} (lines {lines}): {err}") from err
    for spec in coupled:
        reports[spec.role] = _fit_coupled_rows(str(csv_path), spec, rows[spec.role], reports, keep)
    return _finish(reports, specs, head, "csv", str(csv_path), plot_dir, out, keep)


def _fit_coupled_rows(
    file: str,
    spec: ServoSpec,
    rows: Sequence[Measurement],
    reports: Mapping[str, FitReport],
    keep: HeadCalibration | None,
) -> FitReport:
    """Fit a coupled anchor from its CSV rows; neighbours must be calibrated (in this file or kept)."""
    names = [n for n, _ in rows[0].neighbours]
    neutral: list[int] = []
    for name in names:
        if name in reports and reports[name].servo.coupling is None:
            neutral.append(reports[name].servo.neutral_tick)
        elif name not in reports and keep is not None and name in keep and keep[name].coupling is None:
            neutral.append(keep[name].neutral_tick)
        else:
            raise MeasurementCsvError(
                file,
                rows[0].line,
                f"role '{spec.role}': neighbour '{name}' must have an uncoupled calibration "
                "(measure it in this file or keep it from the existing one)",
            )
    inputs = [[m.tick] + [t for _, t in m.neighbours] for m in rows]
    try:
        return fit_coupled_servo(spec, names, neutral, inputs, [m.target for m in rows])
    except CalibrationError as err:
        lines = ", ".join(str(m.line) for m in rows)
        raise type(err)(f"{file} (lines {lines}): {err}") from err


def _finish(
    reports: dict[str, FitReport],
    specs: Sequence[ServoSpec],
    head: str,
    method: str,
    source: str,
    plot_dir: str | os.PathLike[str] | None,
    out: str | os.PathLike[str] | None,
    keep: HeadCalibration | None,
) -> ProcedureResult:
    fitted = {role: r.servo for role, r in reports.items()}
    if keep is not None:
        servos = [fitted.get(s.role, s) for s in keep.servos]
        known = {s.role for s in keep.servos}
        servos += [fitted[s.role] for s in specs if s.role in fitted and s.role not in known]
    else:
        servos = [fitted[s.role] for s in specs if s.role in fitted]
    calibration = HeadCalibration(head, servos, metadata_now(method, source, roles_fitted=sorted(fitted)))
    result = ProcedureResult(calibration, dict(reports))
    if plot_dir is not None:
        for role, report in reports.items():
            result.plots[role] = plot_servo(report.servo, Path(plot_dir) / f"{role}.png", warnings=report.warnings)
    if out is not None:
        result.saved_to = save_calibration(calibration, out)
    return result
