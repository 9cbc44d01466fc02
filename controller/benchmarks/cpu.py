"""The controller's CPU at 50 Hz: the human head's performance played over a pty, the emulator in another
process (`python -m servoface.controller.benchmarks.cpu human` serves it), as a share of one core.

What a Raspberry-Pi-class computer beside a face tracker has to spare: the budget is 10 % of one core. The
share is this process's CPU time (user + system, every thread) over the wall time of the run, in windows
interleaved with the plain stock-SDK loop paced at the same rate on the same port: the host's speed drifts
(the same frames cost 1.6 to 3.5 ms of CPU from one minute to the next on the shared 2-vCPU machine, every
stage alike), so the ratio to that loop in the same rounds is the steadier figure.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator

from servoface.controller.benchmarks.figure import Figure
from servoface.controller.benchmarks.interleave import load_text
from servoface.hardware.driver import FastSyncRead

HEAD = "human"
RATE_HZ = 50.0
BUDGET_PERCENT = 10.0
WINDOWS = 4  # interleaved windows per contender
WINDOW_S = 3.5


def serve(head_name: str) -> None:
    """Serve ``head_name``'s servo chain (its models, at neutral) on a pty; print the path; run until stdin
    closes."""
    from servoface.controller.face import head_calibration
    from servoface.controller.head_servos import servo_specs
    from servoface.hardware.emulator import ServoChain
    from servoface.sim.heads import load_head

    head = load_head(head_name)
    cal = head_calibration(head)
    specs = servo_specs(head, cal)
    chain = ServoChain.create([(s.servo_id, s.model) for s in specs], baud=1_000_000, wire_time=True)
    for s in specs:
        chain.servo(s.servo_id).move_by_hand(cal.by_id(s.servo_id).neutral_tick)
    path = chain.serve_pty()
    sys.stdout.write(path + "\n")
    sys.stdout.flush()
    sys.stdin.read()
    chain.close()


def cpu_budget_figures(quick: bool) -> Iterator[Figure]:
    """The budget figure as a user gets it (``fast_sync_read="auto"``: the driver's start-up probe picks Fast
    Sync Read where every servo answers it, as the emulated head's do), then with plain Sync Read forced
    (one status packet per servo for the SDK to parse: a chain whose firmware lacks Fast Sync Read)."""
    refill = cache_refill_us()
    for fast in ("auto", False):
        yield _cpu_figure(quick, fast, refill)


def cache_refill_us(rounds: int = 60) -> tuple[float, float]:
    """(warm, after one 50 Hz period asleep): median thread CPU of one timeline sample of the shipped human
    performance in µs. The same work costs several times more after a sleep on a shared host (the caches
    are refilled: other tenants evict them while this process sleeps), which is most of what a paced
    frame costs here; printed beside the CPU figures so that a reader can compare machines."""
    from servoface.controller.script import SCRIPTS_DIR, load_script

    script = load_script(SCRIPTS_DIR / "human_performance.toml")
    cold: list[float] = []
    warm: list[float] = []
    for i in range(rounds):
        time.sleep(1.0 / RATE_HZ)
        for k in range(4):  # the first after the sleep, then the same work warm (the last of 3 more)
            t_s = ((4 * i + k) * 0.5 / RATE_HZ) % script.end_s
            c0 = time.thread_time_ns()
            script.sample(t_s)
            (cold if k == 0 else warm).append((time.thread_time_ns() - c0) / 1e3)
    times = {False: warm[2::3], True: cold}
    return statistics.median(times[False]), statistics.median(times[True])


def _cpu_share(run: Callable[[], object]) -> float:
    """This process's CPU time over the wall time of ``run()`` (every thread, user + system)."""
    cpu0, wall0 = time.process_time(), time.perf_counter()
    run()
    return (time.process_time() - cpu0) / max(1e-9, time.perf_counter() - wall0)


def _cpu_figure(quick: bool, fast: FastSyncRead, refill_us: tuple[float, float]) -> Figure:
    """The controller's CPU share at 50 Hz, in windows interleaved with the plain stock-SDK loop paced at 50
    Hz on the same port (Sync Write of the head's goals + Sync Read of every position, nothing else): the
    machine's speed was seen to drift by a third from minute to minute on a shared host, so the ratio of
    the two in the same rounds says what the controller costs above the bare SDK traffic."""
    from servoface.controller.face import Face
    from servoface.controller.loop import FixedRateLoop
    from servoface.controller.performance import play_timeline
    from servoface.controller.script import SCRIPTS_DIR, load_script
    from servoface.hardware.stock_loop import StockSdkLoop

    emulator = EmulatorProcess(HEAD)
    try:
        face = Face.open(HEAD, port=emulator.path, rate_hz=RATE_HZ, fast_sync_read=fast)
        try:
            driver = face.driver
            if driver is None:
                raise RuntimeError("Face.open on a pty gave no driver")
            read_info = driver.fast_read_info
            fast = driver.fast_sync_read  # what the probe chose ("auto") or what was forced
            script = load_script(SCRIPTS_DIR / "human_performance.toml")
            rounds, window_s = (1, 1.5) if quick else (WINDOWS, min(WINDOW_S, script.end_s / WINDOWS))
            stock = StockSdkLoop(driver.bus, list(face.pipeline.last_goals_tick), driver.servo_ids, fast=fast)
            frames: list[int] = []
            achieved: list[float] = []
            timeouts0 = driver.bus.stats.timeouts
            at = [0.0]

            def pipeline_window() -> None:
                result = play_timeline(face.pipeline, script, window_s, rate_hz=RATE_HZ, start_s=at[0])
                at[0] += window_s  # the next window plays on from here (from the start once past the end)
                if at[0] + window_s > script.end_s + 1e-9:
                    at[0] = 0.0
                frames.append(len(result.traces))
                achieved.append(0.0 if result.stats is None else result.stats.achieved_hz)

            def stock_window() -> None:
                goals = dict(face.pipeline.last_goals_tick)  # the head holds where the pipeline left it

                def one_cycle(_: object) -> None:
                    stock.cycle(goals)

                FixedRateLoop(one_cycle, RATE_HZ).run(duration_s=window_s)

            ours: list[float] = []
            theirs: list[float] = []
            for r in range(rounds):  # alternate which goes first
                pair = (pipeline_window, stock_window) if r % 2 == 0 else (stock_window, pipeline_window)
                shares = {fn.__name__: _cpu_share(fn) for fn in pair}
                ours.append(100.0 * shares["pipeline_window"])
                theirs.append(100.0 * shares["stock_window"])
            timeouts = driver.bus.stats.timeouts - timeouts0
        finally:
            face.close(ease_s=0.0)
    finally:
        emulator.close()
    share = statistics.median(ours)
    stock_share = statistics.median(theirs)
    ratios = [a / b for a, b in zip(ours, theirs, strict=True) if b > 0]
    per_frame_ms = share / 100.0 / RATE_HZ * 1e3
    read = ", Fast Sync Read" if fast else ", plain Sync Read"
    return Figure(
        f"controller CPU at {RATE_HZ:g} Hz over a pty ({HEAD}, emulator in another process{read})",
        share,
        "% of a core",
        limit=BUDGET_PERCENT,
        better="lower",
        note=f"median of {rounds} {window_s:g} s windows of the shipped performance "
        f"({', '.join(f'{v:.1f}' for v in ours)} %; {sum(frames)} frames, "
        f"{statistics.median(achieved):.1f} Hz achieved), {per_frame_ms:.2f} ms CPU per "
        f"frame; the plain stock-SDK loop at {RATE_HZ:g} Hz on the same port, interleaved (the same Sync Write + "
        f"Sync Read{' (Fast)' if fast else ''}, no gate, no telemetry): {stock_share:.1f} % "
        f"({', '.join(f'{v:.1f}' for v in theirs)}), so x{statistics.median(ratios) if ratios else 0.0:.2f} the "
        f"bare SDK traffic; one gate check per frame (play_timeline turns the speculative check off; the next "
        f"frame's muscle model + calibration run during the wait); {timeouts} timeouts; read: {read_info}; "
        f"cache refill on this host: a timeline sample takes {refill_us[0]:.0f} us warm and {refill_us[1]:.0f} us "
        f"after one period asleep (x{refill_us[1] / max(1e-9, refill_us[0]):.1f}); {load_text()}",
    )


def serve_servos(n_servos: int) -> None:
    """Serve ``n_servos`` XL330 (ids 1..n, 1 Mbps, wire time on) on a pty; print the path; run until stdin
    closes."""
    from servoface.hardware.emulator import ServoChain

    chain = ServoChain.create(ids=range(1, n_servos + 1), model="XL330-M288", baud=1_000_000, wire_time=True)
    sys.stdout.write(chain.serve_pty() + "\n")
    sys.stdout.flush()
    sys.stdin.read()
    chain.close()


class EmulatorProcess:
    """An emulated chain served from another process (``python -m servoface.controller.benchmarks.cpu``)."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "servoface.controller.benchmarks.cpu", *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.proc.stdout is not None
        self.path = self.proc.stdout.readline().strip()
        if not self.path:
            self.close()
            raise RuntimeError("the emulator process printed no pty path")

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--servos":
        serve_servos(int(sys.argv[2]))
    else:
        serve(sys.argv[1] if len(sys.argv) > 1 else HEAD)
