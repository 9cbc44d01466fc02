"""`servoface bench gate`'s per-frame figures: wall and CPU time side by side, each with its goal."""

from __future__ import annotations

import math

from servoface.controller.benchmarks.gate import _frame_costs_ms, _frame_figures, _gate


def test_gate_frame_figures_report_cpu_beside_wall_with_verdicts() -> None:
    gate = _gate("human", None)
    wall, cpu = _frame_costs_ms(gate, 6, clip=False)
    assert len(wall) == len(cpu) == 6
    assert all(math.isfinite(w) and w >= 0.0 for w in wall) and all(math.isfinite(c) and c >= 0.0 for c in cpu)
    figures = {f.name: f for f in _frame_figures("human", gate, 6)}
    assert set(figures) == {
        "human gate time per frame (median, small steps)",
        "human gate time per frame (p99, small steps)",
        "human gate CPU time per frame (p99, small steps)",
    }
    cpu_p99 = figures["human gate CPU time per frame (p99, small steps)"]
    assert cpu_p99.goal == 3.0 and cpu_p99.unit == "ms"
    assert "thread_time_ns" in cpu_p99.note and "garbage collections" in cpu_p99.note
    assert "CPU median" in figures["human gate time per frame (median, small steps)"].note
