"""What the integration tests check on the wire: Goal Position writes decoded from the emulator log."""

from __future__ import annotations

import numpy as np
from servoface.controller.pipeline import Pipeline
from servoface.hardware.emulator import ServoChain
from servoface.sim.gate import limits as lim


def check_wire(pipeline: Pipeline, chain: ServoChain, start: int = 0) -> int:
    """Every Goal Position write the emulator decoded (from index ``start`` of the log): inside the
    calibration's limits, each step from the same servo's previous goal within the gate's per-frame cap, and
    each change of step within the gate's acceleration bound (`servoface.sim.gate.limits.step_bounds`). Returns how
    many goals were checked."""
    table = pipeline.gate.table
    cal = pipeline.calibration
    index = table.index()
    writes = chain.goal_writes()
    assert writes[start:], "no goal reached the bus"
    last: dict[int, int] = {}
    last_step = np.zeros(table.n, dtype=np.int64)
    for k, (t_s, sid, tick) in enumerate(writes):  # the history before ``start`` primes the step memory
        check = k >= start
        assert sid in index, f"goal for servo {sid}, which the head does not have"
        i = index[sid]
        servo = cal.by_id(sid)
        where = f"t={t_s:.3f}s servo {sid} '{servo.role}'"
        if check:
            assert servo.min_tick <= tick <= servo.max_tick, (
                f"{where}: goal {tick} outside {servo.min_tick}..{servo.max_tick}"
            )
        if sid in last:
            step = tick - last[sid]
            if check:
                cap = int(table.max_step_tick[i])
                assert abs(step) <= cap, f"{where}: step {step} beyond the cap {cap} tick/frame"
                lo, hi = lim.step_bounds(last_step, table)
                assert lo[i] <= step <= hi[i], f"{where}: step {step} after {last_step[i]} outside {lo[i]}..{hi[i]}"
            last_step[i] = step
        last[sid] = tick
    return len(writes) - start
