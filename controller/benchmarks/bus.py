"""`servoface bench bus`: sustained sync-write + sync-read cycles against the wire limit and the stock SDK.

24 XL330-M288 on the in-process emulator port with wire time on, at 1 Mbps and 4 Mbps, Return Delay Time 0
(written to every servo before measuring). Per baud and read (plain Sync Read / Fast Sync Read of Present
Position), three loops on the same chain, interleaved (`interleave`: 20 rounds of one 0.25 s window each):
the plain stock-SDK loop (`servoface.hardware.stock_loop`), `ServoBus` sync write + sync read, and a full
`Driver.cycle`, whose clock runs only in its own windows (`interleave.OwnClock`: its slow telemetry
keeps the schedule of one continuous back-to-back run, floor-rate reads included). Each figure is the
median window rate next to the wire limit from
`servoface.hardware.wire.cycle_budget` (packet sizes, baud, return delay), plus its ratio to the stock SDK
loop (median of per-round ratios); the best window and the machine's load are in the note. The same three
over a pty with the emulator in another process (`servoface emulate`; its CPU then is not the measured
process's, as a real chain's is not) at 1 Mbps sync read and 4 Mbps sync / fast sync read, each with a
pacing check (no window may beat the wire limit: the emulator paces bytes at 10 bit / baud). A
last group of figures splits the CPU time of one cycle (no wire time) between dynamixel-sdk, the emulator and servoface.
"""

from __future__ import annotations

import cProfile
import pstats
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator

from servoface.controller.benchmarks.figure import Figure
from servoface.controller.benchmarks.interleave import OwnClock, Step, interleaved, load_text
from servoface.hardware.bus import ServoBus, open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.errors import BusCorruptError, BusTimeoutError
from servoface.hardware.registers import Register
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.stock_loop import StockSdkLoop
from servoface.hardware.wire import CycleBudget, cycle_budget

N_SERVOS = 24
BAUDS = (1_000_000, 4_000_000)
PTY_CONFIGS = ((1_000_000, False), (4_000_000, False), (4_000_000, True))  # (baud, fast): over a pty
RETURN_DELAY_US = 0
GOAL_RATIO = 0.9
DRIVER_GOAL_RATIO = 0.95
STOCK = "stock SDK loop (GroupSyncWrite + GroupSyncRead)"
DRIVER = "Driver.cycle (telemetry + policy)"
SETTLE = 3  # untimed cycles per window, every loop alike (`interleave.interleaved`: the driver's telemetry
# catch-up after the others' windows is not its steady state)


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
    rounds, window_s = (4, 0.1) if quick else (20, 0.25)
    for baud in BAUDS:
        for fast in (False, True):
            yield from _interleaved_figures(baud, fast, rounds, window_s)
    for baud, fast in PTY_CONFIGS:
        yield from _pty_figures(baud, fast, rounds, window_s)
    yield Figure(
        "return delay time (bench configuration)",
        RETURN_DELAY_US,
        "us",
        better="lower",
        note="Return Delay Time written to every servo before measuring (factory default 500 us)",
    )
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


def contenders(
    open_port: Callable[[], ServoBus], ids: list[int], fast: bool, clock: OwnClock
) -> tuple[dict[str, Step], Driver, list[ServoBus]]:
    """The three loops compared on one chain, each on the port ``open_port`` gives (its own in process; one
    shared over a pty, whose lock admits one controller): the plain stock-SDK loop, servoface's `ServoBus`
    sync write + sync read, and a full `Driver.cycle` (telemetry + fault policy) on ``clock``. They take turns."""
    buses = [open_port() for _ in range(3)]
    stock = StockSdkLoop(buses[0], ids, fast=fast)
    specs = [ServoSpec(sid, "XL330-M288", return_delay_us=RETURN_DELAY_US) for sid in ids]
    # the driver's telemetry schedule runs on the time it has the bus (`interleave.OwnClock`): its windows
    # join up into one back-to-back run, floor-rate reads included, as a driver running on its own sees it
    driver = Driver(buses[2], specs, fast_sync_read=fast, clock=clock)
    driver.configure()
    driver.torque_on()
    bus = buses[1]

    def bus_cycle(n: int) -> None:
        try:
            _cycle(bus, ids, n, fast)
        except (BusTimeoutError, BusCorruptError):
            pass  # counted in the bus's stats (the note's timeouts / corrupt)

    def driver_cycle(n: int) -> None:
        driver.cycle({sid: 2048 + (n & 1) for sid in ids})

    steps: dict[str, Step] = {
        STOCK: lambda n: stock.cycle(2048 + (n & 1)),
        "ServoBus sync write + sync read": bus_cycle,
        DRIVER: driver_cycle,
    }
    return steps, driver, list({id(b): b for b in buses}.values())


def _interleaved_figures(baud: int, fast: bool, rounds: int, window_s: float) -> Iterator[Figure]:
    chain, setup = _chain_and_bus(baud, wire_time=True)
    setup.close()
    clock = OwnClock()
    steps, driver, buses = contenders(lambda: open_bus("emulator", chain=chain, baud=baud), chain.ids, fast, clock)
    try:
        yield from _figures(steps, driver, clock, buses, baud, fast, rounds, window_s, "")
    finally:
        for b in buses:
            b.close()
        chain.close()


class _EmulateProcess:
    """`servoface emulate --ids 1-N --model XL330-M288 --baud B` in another process (wire time on): the
    chain's CPU is not the measured process's, as a real chain's is not. Its pty thread reads the host's baud
    from the pty's termios and paces every byte at 10 bit / baud (`ServoChain.host_write` / `_schedule`)."""

    def __init__(self, baud: int) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "servoface.controller.cli", "emulate", "--ids", f"1-{N_SERVOS}",
             "--model", "XL330-M288", "--baud", str(baud)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        assert self.proc.stdout is not None
        self.path = self.proc.stdout.readline().strip()
        self.stats = ""
        if not self.path.startswith("/"):
            self.close()
            raise RuntimeError(f"servoface emulate printed no pty path: {self.path!r}")

    def close(self) -> None:
        """SIGTERM (the CLI exits 0); keeps its pty thread's punctuality line (late reply bursts)."""
        self.proc.terminate()
        try:
            _, err = self.proc.communicate(timeout=5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _, err = self.proc.communicate()
        self.stats = next((ln[len("# pty: ") :] for ln in (err or "").splitlines() if ln.startswith("# pty: ")), "")


def _pty_figures(baud: int, fast: bool, rounds: int, window_s: float) -> Iterator[Figure]:
    """The same three loops over a pty, the emulator in another process (`servoface emulate` at ``baud``):
    the in-process figures above pay for the emulator's CPU in the measured process, a real chain does not.
    The pty hands a reply burst over when its last byte has arrived (one write, as a USB adapter hands over
    frames), so the controller parses after the wire, not during it."""
    emulator = _EmulateProcess(baud)
    try:
        setup = open_bus("dynamixel", port=emulator.path, baud=baud, warn_latency=False)
        ids = list(range(1, N_SERVOS + 1))
        for sid in ids:
            setup.write(sid, Register.RETURN_DELAY_TIME, RETURN_DELAY_US // 2)
        # one bus for the three: the port lock admits one controller per chain (a second open of the pty
        # raises PortLockedError), and the contenders take turns anyway
        clock = OwnClock()
        steps, driver, buses = contenders(lambda: setup, ids, fast, clock)
        try:
            bests: dict[str, float] = {}
            figures = list(_figures(steps, driver, clock, buses, baud, fast, rounds, window_s, ", over a pty", bests))
            own = _own_budget(driver, baud, fast)
        finally:
            for b in buses:
                b.close()
    finally:
        emulator.close()
    yield from figures
    budget = cycle_budget(N_SERVOS, baud, return_delay_us=RETURN_DELAY_US, fast=fast)
    # each loop against the wire limit of its own packets (the driver's position read may be a byte shorter)
    best = max((b / (own if name == DRIVER else budget).limit_hz for name, b in bests.items()), default=0.0)
    read = "fast sync read" if fast else "sync read"
    yield Figure(
        f"pacing check: best window of the three loops / wire limit, {read} @{baud // 1_000_000}M over a pty",
        best,
        "x wire limit",
        limit=1.0,
        better="lower",
        note="no loop can beat the wire of its own packets: above 1 the emulator process would not pace its bytes "
        "at 10 bit / "
        f"{baud} bps (it reads the baud from the pty's termios); emulator's pty thread: {emulator.stats or 'no stats'}",
    )


def _own_budget(driver: Driver, baud: int, fast: bool) -> CycleBudget:
    """The wire budget of the driver's own packets (its position read's bytes per servo)."""
    return cycle_budget(N_SERVOS, baud, read_len=driver.position_read_bytes, return_delay_us=RETURN_DELAY_US, fast=fast)


def _read_size_note(driver: Driver, baud: int, fast: bool) -> str:
    """What the driver's position read carries per servo next to the stock loop's 4 bytes of Present
    Position, and the wire limit of its own packets (the figure's ratio is to the stock loop's packets)."""
    size = driver.position_read_bytes
    if size == 4:
        return "; positions read 4 bytes per servo, as the stock loop's"
    own = _own_budget(driver, baud, fast)
    return (
        f"; positions read {size} bytes per servo through the position sentinel (witness byte + 16-bit "
        f"position: `servoface.hardware.sentinel`), where the stock loop reads Present Position's 4: its own "
        f"packets' wire limit {own.limit_hz:.1f}/s ({own.bytes_total} B)"
    )


def _figures(
    steps: dict[str, Step],
    driver: Driver,
    clock: OwnClock,
    buses: list[ServoBus],
    baud: int,
    fast: bool,
    rounds: int,
    window_s: float,
    where: str,
    bests: dict[str, float] | None = None,
) -> Iterator[Figure]:
    """The figures of one interleaved run (``bests`` collects every contender's best window rate, by name)."""
    reads0 = dict(driver.telemetry_reads)
    t0 = clock()
    stats = interleaved(steps, STOCK, rounds, window_s, settle=SETTLE, clocks={DRIVER: clock})
    driver_s = clock() - t0  # the driver's own time: its windows, settle cycles included
    load = load_text()
    budget = cycle_budget(N_SERVOS, baud, return_delay_us=RETURN_DELAY_US, fast=fast)
    read = "fast sync read" if fast else "sync read"
    tag = f"{read}, {N_SERVOS} servos @{baud // 1_000_000}M{where}"
    ref = stats[STOCK]
    telemetry = {k: (v - reads0.get(k, 0)) / driver_s for k, v in driver.telemetry_reads.items()}
    timeouts = sum(b.stats.timeouts for b in buses)
    corrupt = sum(b.stats.corrupt for b in buses)
    if bests is not None:
        bests.update((name, st.best) for name, st in stats.items())
    for name, st in stats.items():
        goal = GOAL_RATIO
        if name.startswith("Driver") and baud == BAUDS[0] and not fast:
            goal = DRIVER_GOAL_RATIO
        extra = ""
        if name.startswith("Driver"):
            extra = _read_size_note(driver, baud, fast)
            extra += "; slow telemetry group reads/s " + ", ".join(f"{k} {v:.1f}" for k, v in telemetry.items())
            extra += (
                " (back to back: no idle bus time, so at FaultPolicy.telemetry_floor_share of nominal; the "
                "driver's clock runs only in its own windows, so they join up into one continuous run)"
            )
        yield Figure(
            f"{name}, {tag}",
            st.median,
            "cycles/s",
            limit=budget.limit_hz,
            goal_ratio=goal,
            note=f"median of {rounds} interleaved {window_s:g} s windows, each after {SETTLE} untimed cycles "
            f"(best {st.best:.0f}/s = ratio "
            f"{st.best / budget.limit_hz:.3f}); x{st.median_ratio:.3f} the stock SDK loop in the same rounds "
            f"(median of per-round ratios; stock SDK median {ref.median:.0f}/s); wire limit {budget.bytes_total} B "
            f"x 10 bit / {baud} bps + RDT {RETURN_DELAY_US} us = {budget.wire_time_s * 1e3:.3f} ms{extra}; "
            f"timeouts {timeouts}, corrupt {corrupt}; {load}",
        )
        if name != STOCK:
            yield Figure(
                f"{name} vs stock SDK loop, {tag}",
                st.median_ratio,
                "x SDK loop",
                limit=1.0,
                goal_ratio=1.0 if name.startswith("Driver") else None,
                note=f"median over {rounds} rounds of (this window's rate / the stock SDK loop's window in the "
                f"same round); best round x{max(st.ratios, default=0):.3f}; {load}",
            )
