"""The bus benchmark's pieces (figures are printed by `servoface bench bus`, never asserted on time)."""

from __future__ import annotations

from servoface.controller.benchmarks import bus as bench
from servoface.hardware.registers import Register
from servoface.hardware.wire import cycle_budget


def test_bench_chain_has_zero_return_delay_and_cycles_reach_the_servos() -> None:
    chain, bus = bench._chain_and_bus(4_000_000, wire_time=True)
    try:
        assert {chain.servo(sid).read_register("RETURN_DELAY_TIME") for sid in chain.ids} == {0}
        best, median, per_cycle, cpu_share = bench.measure_rate_hz(bus, chain.ids, fast=True, windows=2, window_s=0.02)
        assert best >= median > 0 and per_cycle > 0 and 0 < cpu_share <= 1.5
        assert len(chain.goal_writes()) % bench.N_SERVOS == 0 and chain.goal_writes()
        assert bus.stats.timeouts == 0 and bus.stats.corrupt == 0
        assert bus.sync_read([1], [Register.PRESENT_POSITION])[1][Register.PRESENT_POSITION] in (2048, 2049)
    finally:
        bus.close()
        chain.close()


def test_cpu_split_names_who_spends_the_time() -> None:
    split = bench.cpu_split_ms(1_000_000, fast=False, cycles=5)
    assert set(split) == {"dynamixel_sdk", "emulator", "servoface", "other"}
    assert split["dynamixel_sdk"] > 0 and split["emulator"] > 0 and split["servoface"] > 0


def test_bench_limit_is_the_wire_arithmetic() -> None:
    assert cycle_budget(24, 1_000_000).bytes_total == (14 + 24 * 5) + (14 + 24) + 24 * 15


def test_pty_figures_at_4m_run_against_another_process_and_never_beat_the_wire() -> None:
    figures = list(bench._pty_figures(4_000_000, True, rounds=1, window_s=0.02))
    rates = [f for f in figures if f.unit == "cycles/s"]
    assert len(rates) == 3 and all(f.value > 0 and "@4M, over a pty" in f.name for f in rates)
    pacing = figures[-1]
    assert pacing.name.startswith("pacing check") and 0 < pacing.value <= 1.0
    assert "reply bursts" in pacing.note  # the emulator process's own account of its pty thread
