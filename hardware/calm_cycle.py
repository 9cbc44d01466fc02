"""The calm cycle: the snapshot's per-servo checks done while the position replies are on the wire.

Most cycles of a running head are calm: every servo answers the position read, no telemetry group is read
or folded, no Alert bit, no servo being rebooted, recovered or re-probed, no fault event. In such a cycle
the only record fields that change after the position read's instruction has gone out are position, its
time, failures and stale, so whether each servo's next state is a capture of its last one
(`ServoRecord.freeze_lazy`) can be decided before the replies are collected (`ServoRecord.calm_base`, at
the start of `cycle_finish`: in the wire wait for a back-to-back caller); what is left after the last
reply is one pass over the replies that updates each record and captures its state. Any other cycle (or a
calm plan that the replies contradict) takes the full path, as before. The snapshot is the same either way
(tests/hardware/test_calm_cycle.py compares every cycle's snapshot under fault injection with one built
field by field, and with a driver that always takes the full path).
"""

from __future__ import annotations

from servoface.hardware.driver_reads import ChainReads
from servoface.hardware.sentinel import TICK_SIGN
from servoface.hardware.servo_record import ServoRecord
from servoface.hardware.snapshot import FaultEvent, ServoState, StateCapture

CalmPlan = dict[int, tuple[ServoRecord, ServoState]]  # servo id -> (its record, the state to capture from)


class CalmCycle(ChainReads):
    """The calm-cycle half of `Driver` (a mixin over `ChainReads`; attributes set by `Driver.__init__`)."""

    _cycle_events: list[FaultEvent]
    _calm_events: int  # events of the cycle when the plan was made (one more: not calm)

    def _plan_calm(self, now: float) -> CalmPlan | None:
        """At the start of `cycle_finish`, before the position replies are collected (a back-to-back caller
        gets there while they are on the wire; the pipeline, after its own computing): if this cycle can be
        calm, each servo's record and the state to capture from, else None. Nothing folded, no group due
        (its read would come after the positions), every servo asked, none rebooting / recovering / missing,
        every state capturable."""
        ids = self._position_ids
        records = self._records
        if ids is None or self._folded is not None or len(ids) != len(records) or self._due_group(now) is not None:
            return None
        plan: CalmPlan = {}
        for sid, rec in records.items():
            if rec.missing or rec.reboot_at_s is not None or rec.recover_at_s is not None:
                return None
            base = rec.calm_base(now)
            if base is None:
                return None
            plan[sid] = (rec, base)
        self._calm_events = len(self._cycle_events)
        return plan

    def _read_positions_calm(self, plan: CalmPlan, now: float) -> dict[int, ServoState | StateCapture] | None:
        """`_read_positions` for a planned calm cycle. If the replies keep it calm (every servo answered the
        first try, no Alert bit, no event): the records updated as `_apply_positions` does and the snapshot's
        captures, in one pass. Else the positions applied as usual and None: the caller takes the full path."""
        ids, registers, got = self._collect_positions(now)
        calm = not self._group_failed and len(got) == len(plan) and not self.bus.alerts
        if not calm or len(self._cycle_events) != self._calm_events:
            self._apply_positions(now, ids, registers, got)
            return None
        position = registers[0]
        sign = TICK_SIGN.get(position)  # through the sentinel: its position's sign bit; None: a direct read
        if sign is not None:  # through the sentinel: every witness byte first (a reset: the full path)
            witness = self._witness
            if any(values[position] & 0xFF != witness.get(sid, -1) for sid, values in got.items()):
                self._apply_positions(now, ids, registers, got)
                return None
        items: dict[int, ServoState | StateCapture] = {}
        for sid, (rec, base) in plan.items():  # `got` holds exactly the ids asked for: every servo's
            tick = got[sid][position]
            if sign is not None:
                tick = ((tick >> 8) ^ sign) - sign
            rec.position_tick = tick
            rec.position_t_s = now
            rec.failures = 0
            rec.stale = False
            items[sid] = (base, tick, now, rec.goal_tick, False)
        return items
