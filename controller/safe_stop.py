"""The one stop path: every way a run ends — normal end, Ctrl-C (once or twice), SIGTERM, SIGHUP, an
exception, a bus failure, an interrupted start-up — ends here, and leaves the head safe.

`safe_stop(pipeline, driver)`:

1. **Ease to neutral**, through the pipeline (so every frame passes the twin gate and its caps): the AUs
   go from where the face is to none over ``ease_s`` (minimum jerk), then neutral is held until the gate
   passes it whole — at most ``max_ease_s`` in all. Skipped when the bus is down; stopped by any error.
   ``hurry()`` (a second Ctrl-C) does not cut torque mid-pose: from then on neutral is asked for at once,
   so the head travels there as fast as the gate's speed and acceleration caps allow (per second of wire
   time), for at most ``hurry_s`` more; then torque goes off.
2. **Torque off on every servo**, each tried `FaultPolicy.torque_off_attempts` times, carrying on past the
   ones that fail (missing servos are tried too), then the Bus Watchdog disarmed on those reached.
3. A `StopReport`: the servos that could **not** be reached (their torque may still be on), the ones that
   ended latched or missing, and how the easing went. ``report.safe`` is False when any servo was not
   reached; the CLI turns the report into its closing lines and exit status.

The head service (``controller/service``) and the CLI both call this; nothing else switches a head off.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from servoface.controller.frame import AUFrame
from servoface.controller.pipeline import FrameTrace, Pipeline
from servoface.controller.timeline import min_jerk
from servoface.hardware.driver import Driver
from servoface.hardware.snapshot import ChainSnapshot, peek_state

EASE_S = 0.8  # default easing to neutral
MAX_EASE_S = 2.5  # the easing never takes longer than this (then torque goes off wherever the head is)
HURRY_S = 1.0  # after a second stop signal: at most this long straight to neutral at the gate's caps


@dataclass(frozen=True)
class StopReport:
    """How a run ended. Ids are servo ids."""

    reason: str  # "end", "SIGINT", "SIGTERM", "SIGHUP", "error", "bus failure", "start-up interrupted"
    eased: bool  # the gate passed neutral whole before torque went off
    ease_s: float
    ease_note: str  # why the easing was skipped or cut ("" when it reached neutral)
    unreached: tuple[int, ...] = ()  # torque off not confirmed: may still be powered
    latched: tuple[int, ...] = ()  # latched off by the fault policy (needs Driver.clear_fault)
    missing: tuple[int, ...] = ()  # out of service (MISSING) at the end, yet torque off confirmed
    error: str = ""  # what ended the run, when an error did (the head service's loop crash, a bus failure)

    @property
    def safe(self) -> bool:
        """Every servo confirmed torque off."""
        return not self.unreached

    @property
    def torque_off(self) -> bool:
        """Same as ``safe``: torque-off confirmed on every servo."""
        return self.safe

    @property
    def clean(self) -> bool:
        """Safe, and no servo latched or missing."""
        return self.safe and not self.latched and not self.missing

    def lines(self) -> list[str]:
        """Closing lines for a terminal or a log."""
        ease = (
            f"eased to neutral in {self.ease_s:.2f} s" + (f" ({self.ease_note})" if self.ease_note else "")
            if self.eased
            else f"easing {'cut' if self.ease_s > 0 else 'skipped'} ({self.ease_note})"
        )
        out = [f"stop ({self.reason}): {ease}; torque off"]
        if self.unreached:
            out.append(
                f"  NOT REACHED: servo(s) {_ids(self.unreached)}: torque-off not confirmed, they may still be "
                "powered — switch the servo supply off"
            )
        else:
            out[0] += " on every servo"
        if self.latched:
            out.append(f"  latched: servo(s) {_ids(self.latched)} (a fault latched them off; see the fault table)")
        if self.missing:
            out.append(
                f"  missing: servo(s) {_ids(self.missing)} out of service at the end (stopped answering during "
                "the run); torque off confirmed"
            )
        return out


def _ids(ids: tuple[int, ...]) -> str:
    return ", ".join(str(i) for i in ids)


def bus_problem(snapshot: ChainSnapshot | None) -> str | None:
    """Why driving cannot go on (the port failed, or no servo answers), else None."""
    if snapshot is None:
        return None
    if not snapshot.bus_connected:
        return "the port failed (adapter unplugged, emulator gone?)"
    servos = snapshot.servos
    if not servos:
        return None
    for sid in servos:  # (`peek_state`: a driver's snapshot builds no state for this; every frame)
        peeked = peek_state(servos, sid)
        if peeked is None or not peeked[0].missing:
            return None
    return "no servo answers"


def ease_to_neutral(
    pipeline: Pipeline,
    from_aus: Mapping[str, float] | None = None,
    *,
    ease_s: float = EASE_S,
    max_ease_s: float = MAX_EASE_S,
    hurry: Callable[[], bool] = lambda: False,
    hurry_s: float = HURRY_S,
    on_frame: Callable[[FrameTrace], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> tuple[bool, float, str]:
    """(reached neutral, seconds spent, note). Frames at the pipeline's rate, each through the gate; once
    ``hurry()`` is true, neutral is the target at once (the gate's caps set the pace) for ``hurry_s`` more."""
    start_aus = {k: float(v) for k, v in (from_aus or {}).items()}
    period = 1.0 / pipeline.rate_hz
    ease_s = max(0.0, min(float(ease_s), float(max_ease_s)))
    t0 = clock()
    k = 0
    previous_sent: dict[int, int] | None = None
    hurried_at: float | None = None
    while True:
        now = clock()
        elapsed = now - t0
        if hurried_at is None and hurry():
            hurried_at = elapsed
        if hurried_at is not None and elapsed - hurried_at > hurry_s:
            return False, elapsed, f"a second stop signal: neutral not reached within {hurry_s:g} s at the gate's caps"
        if elapsed > max_ease_s:
            return False, elapsed, f"neutral not reached within {max_ease_s:g} s"
        if (problem := bus_problem(pipeline.last_snapshot)) is not None:
            return False, elapsed, problem
        last = pipeline.last_cycle_s
        if last is not None and time.monotonic() - last < period:
            sleep(max(0.0, min(period, last + period - time.monotonic())))
        if hurried_at is not None:
            aus: dict[str, float] = {}  # straight to neutral: the gate clips each frame to its caps
        else:
            s = 1.0 if ease_s <= 0 else min(1.0, elapsed / ease_s)
            keep = 1.0 - min_jerk(s)
            aus = {au: v * keep for au, v in start_aus.items() if abs(v * keep) > 1e-9}
        trace = pipeline.step(AUFrame(elapsed, aus), elapsed)
        if on_frame is not None:
            on_frame(trace)
        k += 1
        arrived = not aus and trace.goals_sent == trace.goals_requested
        if arrived or (not aus and trace.goals_sent == previous_sent and trace.verdict == "reject"):
            note = "" if hurried_at is None else "hurried by a second stop signal"
            if not arrived:
                note = "the gate refuses to move further toward neutral"
            return arrived, clock() - t0, note
        previous_sent = trace.goals_sent
        next_due = t0 + k * period
        wait = next_due - clock()
        if wait > 0:
            sleep(min(wait, period))


def safe_stop(
    pipeline: Pipeline | None,
    driver: Driver | None,
    *,
    from_aus: Mapping[str, float] | None = None,
    ease: bool = True,
    ease_s: float = EASE_S,
    max_ease_s: float = MAX_EASE_S,
    hurry: Callable[[], bool] = lambda: False,
    reason: str = "end",
    on_frame: Callable[[FrameTrace], None] | None = None,
    error: str = "",
    skip_note: str = "",
) -> StopReport:
    """Ease (bounded), torque off every servo (retried, carrying on), report. Never raises for bus trouble."""
    eased, spent, note = False, 0.0, "no pipeline"
    if driver is None:
        return StopReport(reason, False, 0.0, "no bus", error=error)
    if pipeline is not None and ease:
        try:
            eased, spent, note = ease_to_neutral(
                pipeline, from_aus, ease_s=ease_s, max_ease_s=max_ease_s, hurry=hurry, on_frame=on_frame
            )
        except Exception as err:  # noqa: BLE001 - whatever broke, torque still goes off below
            eased, note = False, f"easing failed: {type(err).__name__}: {err}"
    elif not ease:
        note = skip_note or "not asked"
    unreached = driver.close(torque_off=True)
    problems = driver.servo_problems()
    missing = tuple(i for i in problems["missing"] if i not in unreached)
    return StopReport(reason, eased, spent, note, unreached, problems["latched"], missing, error)
