"""`servoface bench pty [--minutes M] [--quick]`: a sync-read loop over the pty under CPU load.

The emulator runs as its own process (`servoface emulate`, 24 x XL330-M288 at 1 Mbps, Return Delay Time 0)
and servoface's Dynamixel bus drives it through the pseudo-terminal (the stock SDK's packets, CRC and reply
window, as `servoface play --port` uses it). Meanwhile 8
busy processes (pure Python spin loops, one per ``LOAD_PROCESSES``) keep every core of the machine
runnable, so the emulator has to be scheduled inside the SDK's ~34 ms reply window against them. Each cycle
is one Sync Write of Goal Position and one read of Present Position, alternating Sync Read and Fast Sync
Read. Figures: reads that failed (timeouts or corrupt replies: goal 0), the cycle rate next to the wire
limit, the load average seen, and the pty server's cost per cycle (wake-ups and writes, measured
in-process in a short run without the extra load).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any

from servoface.controller.benchmarks.figure import Figure
from servoface.hardware.wire import cycle_budget

N_SERVOS = 24
BAUD = 1_000_000
LOAD_PROCESSES = 8
DEFAULT_MINUTES = 2.0
QUICK_MINUTES = 0.15


def _burners(n: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def _stop(procs: list[subprocess.Popen[Any]]) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def _emulator() -> tuple[subprocess.Popen[str], str]:
    cmd = [sys.executable, "-m", "servoface.controller.cli", "emulate", "--ids", f"1-{N_SERVOS}", "--baud", str(BAUD)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    path = proc.stdout.readline().strip()
    if not path.startswith("/dev/"):
        _stop([proc])
        raise RuntimeError(f"servoface emulate did not print a pty path (got {path!r})")
    return proc, path


def _open_bus(path: str) -> Any:
    """servoface's Dynamixel bus on ``path``, Return Delay Time 0 on every servo."""
    from servoface.hardware.bus import open_bus
    from servoface.hardware.registers import Register

    bus = open_bus("dynamixel", port=path, baud=BAUD)
    for sid in range(1, N_SERVOS + 1):
        bus.write(sid, Register.RETURN_DELAY_TIME, 0)
    return bus


def _bus_cycle(bus: Any, ids: list[int], n: int) -> tuple[str, bool]:
    """One Sync Write + read through servoface's Dynamixel bus; (kind, ok)."""
    from servoface.hardware.errors import BusCorruptError, BusTimeoutError
    from servoface.hardware.registers import Register

    fast = bool(n & 1)
    bus.sync_write(Register.GOAL_POSITION, {sid: 2048 + (n & 1) * 8 for sid in ids})
    try:
        bus.sync_read(ids, (Register.PRESENT_POSITION,), fast=fast)
    except (BusTimeoutError, BusCorruptError):
        return ("fast" if fast else "sync"), False
    return ("fast" if fast else "sync"), True


def loop_under_load(minutes: float, load_processes: int = LOAD_PROCESSES) -> dict[str, Any]:
    """Run the loop for ``minutes`` through servoface's Dynamixel bus (the stock SDK's packets, CRC and
    reply window, as `servoface play --port` uses it); returns counts, rate and load averages."""
    emulator, path = _emulator()
    burners: list[subprocess.Popen[bytes]] = []
    bus: Any = None
    ids = list(range(1, N_SERVOS + 1))
    try:
        bus = _open_bus(path)
        burners = _burners(load_processes)
        time.sleep(2.0)  # let the load settle in
        load_start = os.getloadavg()[0]
        counts = {"sync": 0, "fast": 0, "sync_failed": 0, "fast_failed": 0}
        t0 = time.perf_counter()
        end = t0 + minutes * 60.0
        n = 0
        while time.perf_counter() < end:
            kind, ok = _bus_cycle(bus, ids, n)
            counts[kind] += 1
            if not ok:
                counts[kind + "_failed"] += 1
            n += 1
        elapsed = time.perf_counter() - t0
        load_end = os.getloadavg()[0]
    finally:
        _stop(burners)
        if bus is not None:
            bus.close()
        _stop([emulator])
    err = emulator.stderr.read() if emulator.stderr is not None else ""
    stats = [line for line in err.splitlines() if line.startswith("# pty: ")]
    pty = stats[-1][len("# pty: ") :] if stats else "no stats"
    late = re.search(r"(\d+) handed over more than", pty)
    return {
        **counts,
        "cycles": float(n),
        "elapsed_s": elapsed,
        "load_start": load_start,
        "load_end": load_end,
        "late_bursts": float(late.group(1)) if late else -1.0,
        "pty_stats": pty,
    }


def pty_cost_per_cycle(cycles: int = 300) -> tuple[float, float]:
    """(select wake-ups, writes) of the pty server per sync-write + sync-read cycle (in-process, no load)."""
    from servoface.hardware.emulator import ServoChain

    chain = ServoChain.create(ids=range(1, N_SERVOS + 1), baud=BAUD)
    try:
        bus = _open_bus(chain.serve_pty())
        server: Any = chain._pty  # noqa: SLF001 - the benchmark reads the server's own counters
        ids = list(range(1, N_SERVOS + 1))
        w0, n0 = server.wakeups, server.writes
        for n in range(cycles):
            _bus_cycle(bus, ids, 2 * n)  # plain Sync Read
        bus.close()
        return (server.wakeups - w0) / cycles, (server.writes - n0) / cycles
    finally:
        chain.close()


def run(quick: bool = False, minutes: float | None = None) -> Iterator[Figure]:
    wake, writes = pty_cost_per_cycle(100 if quick else 300)
    yield Figure("pty server wake-ups per cycle (24 servos)", wake, "1/cycle", note="select() calls; was ~49")
    yield Figure("pty server writes per cycle (24 servos)", writes, "1/cycle", note="write() calls; was ~47")
    duration = minutes if minutes is not None else QUICK_MINUTES if quick else DEFAULT_MINUTES
    r = loop_under_load(duration)
    load = f"+{LOAD_PROCESSES} busy processes, load avg {r['load_start']:.1f} -> {r['load_end']:.1f}"
    failed = r["sync_failed"] + r["fast_failed"]
    yield Figure(
        f"pty read failures in {duration:g} min under load",
        failed,
        "reads",
        goal=0,
        better="lower",
        note=f"{load}; {int(r['sync'])} sync ({int(r['sync_failed'])} failed), "
        f"{int(r['fast'])} fast ({int(r['fast_failed'])} failed); emulator: {r['pty_stats']}",
    )
    yield Figure(
        "pty reply bursts handed over > 10 ms late (emulator side)",
        r["late_bursts"],
        "bursts",
        better="lower",
        note="the emulator's own punctuality (the reply window is ~34 ms); a failed read with none late was "
        "lost in the kernel or the client",
    )
    budget = cycle_budget(N_SERVOS, BAUD)
    yield Figure(
        "pty cycle rate under load (SW + SR/FSR, 24 servos)",
        r["cycles"] / r["elapsed_s"],
        "Hz",
        limit=budget.limit_hz,
        note=f"{load}; {os.cpu_count()} cores",
    )
