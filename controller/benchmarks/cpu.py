"""The controller's CPU at 50 Hz: the human head's performance played over a pty, the emulator in another
process (`python -m servoface.controller.benchmarks.cpu human` serves it), as a share of one core.

What a Raspberry-Pi-class computer beside a face tracker has to spare: the budget is 10 % of one core. The
share is this process's CPU time (user + system, every thread) over the wall time of the run.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator

from servoface.controller.benchmarks.figure import Figure
from servoface.controller.benchmarks.interleave import load_text

HEAD = "human"
RATE_HZ = 50.0
BUDGET_PERCENT = 10.0


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
    """The budget figure with plain Sync Read (the default), then with Fast Sync Read (one combined status
    packet for the SDK to parse instead of one per servo; firmware support needed)."""
    for fast in (False, True):
        yield _cpu_figure(quick, fast)


def _cpu_figure(quick: bool, fast: bool) -> Figure:
    from servoface.controller.face import Face
    from servoface.controller.performance import play_timeline
    from servoface.controller.script import SCRIPTS_DIR, load_script

    proc = subprocess.Popen(
        [sys.executable, "-m", "servoface.controller.benchmarks.cpu", HEAD],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        if not path:
            raise RuntimeError("the emulator process printed no pty path")
        face = Face.open(HEAD, port=path, rate_hz=RATE_HZ, fast_sync_read=fast)
        try:
            script = load_script(SCRIPTS_DIR / "human_performance.toml")
            duration_s = 3.0 if quick else min(30.0, script.end_s)
            cpu0, wall0 = time.process_time(), time.perf_counter()
            result = play_timeline(face.pipeline, script, duration_s, rate_hz=RATE_HZ, keep_traces=True)
            wall_s = time.perf_counter() - wall0
            cpu_s = time.process_time() - cpu0
            stats = face.driver.bus.stats if face.driver is not None else None
        finally:
            face.close(ease_s=0.0)
    finally:
        if proc.stdin is not None:
            proc.stdin.close()
        try:
            proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
    frames = len(result.traces)
    read = ", Fast Sync Read" if fast else ""
    return Figure(
        f"controller CPU at {RATE_HZ:g} Hz over a pty ({HEAD}, emulator in another process{read})",
        100.0 * cpu_s / wall_s,
        "% of a core",
        limit=BUDGET_PERCENT,
        better="lower",
        note=f"process CPU {cpu_s:.2f} s over {wall_s:.1f} s wall, {frames} frames "
        f"({0.0 if result.stats is None else result.stats.achieved_hz:.1f} Hz achieved) of the shipped performance, "
        f"{cpu_s / max(1, frames) * 1e3:.2f} ms CPU per frame; one gate check per frame (play_timeline turns "
        f"the speculative check off; the next frame's muscle model + calibration run during the wait); "
        f"{0 if stats is None else stats.timeouts} timeouts; {load_text()}",
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
