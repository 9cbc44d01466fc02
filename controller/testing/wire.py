"""Wire assertions: what the emulator received, checked against the calibrated limits, the gate's speed and
acceleration caps and the servos' torque state. Each check returns its violations (one line per servo and
event, naming the servo, its role and the chain time); each ``assert_*`` raises AssertionError listing
them. On real servos only the end state can be read back: checks of the write history then warn
(`WireNotObservedWarning`) instead of passing silently."""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping

import numpy as np
from servoface.sim.gate import limits as lim
from servoface.testing.limits import WireLimits
from servoface.testing.record import GoalWrite, TorqueWrite, WireRecord

SHOWN = 20  # violations listed in one failure message


class WireNotObservedWarning(UserWarning):
    """A check of the write history was asked for on a chain whose wire nobody recorded (real servos)."""


def fail(title: str, violations: list[str], record: WireRecord) -> None:
    """Raise AssertionError listing ``violations`` (if any) under ``title``."""
    if not violations:
        return
    more = f"\n  ... and {len(violations) - SHOWN} more" if len(violations) > SHOWN else ""
    lines = "\n  ".join(violations[:SHOWN])
    raise AssertionError(f"{title} ({record.source}), {len(violations)} violation(s):\n  {lines}{more}")


def observed_or_warn(record: WireRecord, check: str) -> bool:
    """True when the record has the write history; else warn that ``check`` was not made (real servos)."""
    if record.observed:
        return True
    warnings.warn(
        WireNotObservedWarning(
            f"{check}: not checked on {record.source}; the write history is seen only on the emulator"
        ),
        stacklevel=3,
    )
    return False


def warn_uncapped(limits: WireLimits) -> None:
    """Say which servos' steps the caps cannot check (no known speed for their model)."""
    if limits.uncapped:
        warnings.warn(
            WireNotObservedWarning(
                f"goal steps of servos {list(limits.uncapped)} not checked: no known speed for their model"
            ),
            stacklevel=3,
        )


def _events(record: WireRecord) -> list[GoalWrite | TorqueWrite]:
    events: list[GoalWrite | TorqueWrite] = [*(record.goals or ()), *(record.torque_writes or ())]
    return sorted(events, key=lambda e: (e.seq, isinstance(e, TorqueWrite)))


# ---- checks of the history (emulator only) ------------------------------------------------------------
def goal_limit_violations(record: WireRecord, limits: WireLimits) -> list[str]:
    """Goals outside the servo's limits, and goals to servos the limits do not know."""
    out = []
    for g in record.goals or ():
        s = limits.servos.get(g.servo_id)
        if s is None:
            out.append(
                f"t={g.t_s:.3f}s servo {g.servo_id}: goal {g.goal_tick} tick to a servo with no limits "
                f"({limits.source})"
            )
        elif not s.min_tick <= g.goal_tick <= s.max_tick:
            out.append(
                f"t={g.t_s:.3f}s {s.label}: goal {g.goal_tick} tick outside its {limits.source} limits "
                f"{s.min_tick}..{s.max_tick} tick"
            )
    return out


def goal_step_violations(record: WireRecord, limits: WireLimits) -> list[str]:
    """Steps between consecutive goals of a servo (while its torque is on) beyond the gate's per-frame speed
    cap, or speeding up by more than its acceleration bound (`servoface.sim.gate.limits.step_bounds`). The
    first goal after torque-on is a step from where the servo stood."""
    table = limits.table
    if table is None:
        return []
    index = table.index()
    last: dict[int, int | None] = {}
    last_step = np.zeros(table.n, dtype=np.int64)
    out = []
    for e in _events(record):
        i = index.get(e.servo_id)
        if i is None:
            continue
        if isinstance(e, TorqueWrite) or not e.torque_on:  # torque changed or off: the next move starts at rest
            last[e.servo_id] = None
            last_step[i] = 0
            continue
        ref = last.get(e.servo_id)
        start = e.present_tick if ref is None else ref
        step = e.goal_tick - start
        where = f"t={e.t_s:.3f}s {limits.label(e.servo_id)}"
        cap = int(table.max_step_tick[i])
        frm = "from where it stood" if ref is None else "from its previous goal"
        if abs(step) > cap:
            out.append(
                f"{where}: goal {e.goal_tick} tick is a step of {step} tick {frm}, beyond the cap {cap} tick/frame"
            )
        else:
            lo, hi = lim.step_bounds(last_step, table)
            if not lo[i] <= step <= hi[i]:
                out.append(
                    f"{where}: step {step} tick after {int(last_step[i])} speeds up beyond "
                    f"{int(table.max_speedup_tick[i])} tick/frame^2 (allowed {int(lo[i])}..{int(hi[i])})"
                )
        last[e.servo_id] = e.goal_tick
        last_step[i] = step
    return out


def torque_off_goal_violations(record: WireRecord, limits: WireLimits, *, pin_tolerance_tick: int = 1) -> list[str]:
    """Goals that reached a servo while its torque was off, other than pinning it where it stands (Goal :=
    Present before torque-on; a servo standing outside its limits may be pinned anywhere between where it
    stands and the nearest limit): any other goal makes the servo jump when torque comes on, or is a command
    the code believes moves a servo that is not holding."""
    out = []
    for g in record.goals or ():
        if g.torque_on:
            continue
        s = limits.servos.get(g.servo_id)
        edge = g.present_tick if s is None else min(max(g.present_tick, s.min_tick), s.max_tick)
        lo, hi = min(edge, g.present_tick) - pin_tolerance_tick, max(edge, g.present_tick) + pin_tolerance_tick
        if not lo <= g.goal_tick <= hi:
            out.append(
                f"t={g.t_s:.3f}s {limits.label(g.servo_id)}: goal {g.goal_tick} tick written while its torque was "
                f"off (it stood at {g.present_tick} tick): torque-on would jump it {g.goal_tick - g.present_tick} tick"
            )
    return out


# ---- checks of the end state (emulator and real servos) -----------------------------------------------
def torque_violations(
    record: WireRecord, limits: WireLimits, *, on: Iterable[int] = (), off: Iterable[int] = ()
) -> list[str]:
    out = []
    for sid, want in [*((i, True) for i in on), *((i, False) for i in off)]:
        end = record.end.get(sid)
        if end is None:
            out.append(f"{limits.label(sid)}: not on the chain (have {sorted(record.end)})")
        elif end.torque_on != want:
            state = "left on" if end.torque_on else "off"
            out.append(
                f"{limits.label(sid)}: torque {state} at the end, expected {'on' if want else 'off'} "
                f"(present {end.present_tick} tick, goal {end.goal_tick} tick, "
                f"hardware error 0x{end.hardware_error:02x})"
            )
    return out


def position_violations(
    record: WireRecord,
    limits: WireLimits,
    expected_tick: Mapping[int, int],
    *,
    tolerance_tick: int = 2,
    what: str = "expected",
) -> list[str]:
    out = []
    for sid, want in expected_tick.items():
        end = record.end.get(sid)
        if end is None:
            out.append(f"{limits.label(sid)}: not on the chain (have {sorted(record.end)})")
        elif abs(end.present_tick - int(want)) > tolerance_tick:
            out.append(
                f"{limits.label(sid)}: stands at {end.present_tick} tick, {what} {int(want)} tick "
                f"(off by {end.present_tick - int(want)}, tolerance {tolerance_tick})"
            )
    return out
