"""The pty-under-load benchmark's pieces (figures are printed by `servoface bench pty`, never asserted on time)."""

from __future__ import annotations

import sys

import pytest
from servoface.controller.benchmarks import pty_load as bench

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")


def test_pty_server_wakes_a_few_times_per_cycle_not_per_byte() -> None:
    """One wake-up for the instruction(s), one for the reply burst: far below one per reply byte."""
    wake, writes = bench.pty_cost_per_cycle(30)
    assert 1 <= wake <= 6
    assert 0.9 <= writes <= 2


def test_loop_runs_against_a_separate_emulator_process() -> None:
    r = bench.loop_under_load(0.02, load_processes=1)
    assert r["cycles"] > 0 and r["sync"] + r["fast"] == r["cycles"]
    assert r["elapsed_s"] > 0
