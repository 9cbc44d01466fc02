"""`servoface bench bus`: sustained sync-write + sync-read cycles against the wire limit.

24 XL330-M288 on the in-process emulator port with wire time on, at 1 Mbps and 4 Mbps, Return Delay Time 0
(written to every servo before measuring). Per baud: cycles/s with a plain Sync Read and with Fast Sync Read
of Present Position, each next to the wire limit from `servoface.hardware.wire.cycle_budget` (packet sizes, baud,
return delay). Rates are the median of 20 windows of 0.1 s (the best window is in the note; the machine is shared; the
median single cycle and the on-CPU share are in the note). A last group of figures splits the CPU time of
one cycle (no wire time) between dynamixel-sdk, the emulator and servoface: where the time goes.
"""

from __future__ import annotations

import cProfile
import pstats
import statistics
import time
from collections.abc import Iterator

from servoface.controller.benchmarks.figure import Figure
from servoface.hardware.bus import ServoBus, open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.registers import Register
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.wire import cycle_budget

N_SERVOS = 24
BAUDS = (1_000_000, 4_000_000)
RETURN_DELAY_US = 0
GOAL_RATIO = 0.9


def _chain_and_bus(baud: int, wire_time: bool) -> tuple[ServoChain, ServoBus]:
    chain = ServoChain.create(ids=range(1, N_SERVOS + 1), model="XL330-M288", baud=baud, wire_time=wire_time)
    bus = open_bus("emulator", chain=chain, baud=baud)
    for sid in chain.ids:
        bus.write(sid, Register.RETURN_DELAY_TIME, RETURN_DELAY_US // 2)
    return chain, bus


def _cycle(bus: ServoBus, ids: list[int], n: int, fast: bool) -> None:
    bus.sync_write(Register.GOAL_POSITION, {sid: 2048 + (n & 1) for sid in ids})
    bus.sync_read(ids, (Register.PRESENT_POSITION,), fast=fast)


def measure_rate_hz(
    bus: ServoBus, ids: list[int], fast: bool, windows: int, window_s: float
) -> tuple[float, float, float, float]:
    """Cycles per second: (best window, median window, median single cycle), over ``windows`` windows of
    ``window_s``; and the share of wall time this process was on a CPU (the bus yields on empty reads, so
    under 1 means other processes ran meanwhile)."""
    rates = []
    cycle_s: list[float] = []
    n = 0
    cpu0, wall0 = time.process_time(), time.perf_counter()
    for _ in range(windows):
        count, t0 = 0, time.perf_counter()
        t_prev = t0
        while (elapsed := time.perf_counter() - t0) < window_s:
            _cycle(bus, ids, n, fast)
            now = time.perf_counter()
            cycle_s.append(now - t_prev)
            t_prev = now
            n += 1
            count += 1
        rates.append(count / elapsed)
    cpu_share = (time.process_time() - cpu0) / (time.perf_counter() - wall0)
    return max(rates), statistics.median(rates), 1.0 / statistics.median(cycle_s), cpu_share


def cpu_split_ms(baud: int, fast: bool, cycles: int) -> dict[str, float]:
    """CPU ms per cycle (no wire time) by who spends it: dynamixel_sdk, emulator, servoface driver, other."""
    chain, bus = _chain_and_bus(baud, wire_time=False)
    ids = chain.ids
    t0 = time.perf_counter()
    for n in range(cycles):
        _cycle(bus, ids, n, fast)
    wall = time.perf_counter() - t0  # unprofiled: cProfile itself inflates Python-heavy code several times
    profile = cProfile.Profile()
    profile.enable()
    for n in range(cycles):
        _cycle(bus, ids, n, fast)
    profile.disable()
    bus.close()
    split = {"dynamixel_sdk": 0.0, "emulator": 0.0, "servoface": 0.0, "other": 0.0}
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    for (filename, _, _), (_, _, tottime, _, _) in stats.items():
        key = (
            "dynamixel_sdk"
            if "dynamixel_sdk" in filename
            else "emulator"
            if "hardware/emulator" in filename
            else "servoface"
            if "/hardware/" in filename
            else "other"
        )
        split[key] += tottime
    total = sum(split.values()) or 1.0
    return {k: v / total * wall / cycles * 1e3 for k, v in split.items()}  # shares of the unprofiled wall time


def run(quick: bool = False) -> Iterator[Figure]:
    windows, window_s = (4, 0.1) if quick else (20, 0.1)
    for baud in BAUDS:
        chain, bus = _chain_and_bus(baud, wire_time=True)
        ids = chain.ids
        tag = f"{N_SERVOS} servos @{baud // 1_000_000}M"
        for fast, label in ((False, "sync write + sync read"), (True, "sync write + fast sync read")):
            budget = cycle_budget(N_SERVOS, baud, return_delay_us=RETURN_DELAY_US, fast=fast)
            best, median, per_cycle, cpu_share = measure_rate_hz(bus, ids, fast, windows, window_s)
            yield Figure(
                f"{label}, {tag}",
                median,
                "cycles/s",
                limit=budget.limit_hz,
                goal_ratio=GOAL_RATIO,
                note=f"median of {windows}x{window_s:g}s windows (best window {best:.0f}/s = ratio "
                f"{best / budget.limit_hz:.3f}, "
                f"median single cycle {per_cycle:.0f}/s = ratio {per_cycle / budget.limit_hz:.3f}); "
                "wire limit "
                f"{budget.bytes_total} B x 10 bit / {baud} bps + RDT {RETURN_DELAY_US} us = "
                f"{budget.wire_time_s * 1e3:.3f} ms; timeouts {bus.stats.timeouts}, "
                f"corrupt {bus.stats.corrupt}; on-CPU share {cpu_share:.2f} (other processes ran the rest)",
            )
        bus.close()
        chain.close()
    yield Figure(
        "return delay time (bench configuration)",
        RETURN_DELAY_US,
        "us",
        better="lower",
        note="Return Delay Time written to every servo before measuring (factory default 500 us)",
    )
    yield from _driver_cycle(quick)
    cycles = 100 if quick else 400
    for baud in BAUDS[-1:]:
        for fast in (False, True):
            split = cpu_split_ms(baud, fast, cycles)
            total = sum(split.values())
            wire_ms = cycle_budget(N_SERVOS, baud, fast=fast).wire_time_s * 1e3
            detail = ", ".join(f"{k} {v:.3f} ms" for k, v in split.items())
            yield Figure(
                f"CPU per cycle, no wire time, {'fast ' if fast else ''}sync read, {N_SERVOS} servos",
                total,
                "ms",
                limit=wire_ms,
                better="lower",
                note=f"{detail} (cProfile tottime shares of the unprofiled time); the SDK busy-waits, so "
                "CPU that does not overlap the wire adds to every cycle",
            )


def _driver_cycle(quick: bool) -> Iterator[Figure]:
    """A full `Driver.cycle` (sync write + position read + round-robin telemetry + policy) at 1 Mbps."""
    baud = BAUDS[0]
    chain, bus = _chain_and_bus(baud, wire_time=True)
    specs = [ServoSpec(sid, "XL330-M288", return_delay_us=RETURN_DELAY_US) for sid in chain.ids]
    driver = Driver(bus, specs)
    driver.configure()
    driver.torque_on()
    goals = {sid: 2048 for sid in chain.ids}
    duration_s = 0.5 if quick else 2.0
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < duration_s:
        goals = {sid: 2048 + (n & 1) for sid in chain.ids}
        driver.cycle(goals)
        n += 1
    rate = n / (time.perf_counter() - t0)
    limit = cycle_budget(N_SERVOS, baud, return_delay_us=RETURN_DELAY_US).limit_hz
    yield Figure(
        f"Driver.cycle (incl. telemetry + policy), {N_SERVOS} servos @1M",
        rate,
        "cycles/s",
        limit=limit,
        goal_ratio=0.95,
        note="limit = sync write + sync read only; the driver also reads one slow telemetry group "
        "on ~1 cycle in 4 (status 10 Hz, motion 10 Hz, thermal 2 Hz at this rate)",
    )
    bus.close()
    chain.close()
