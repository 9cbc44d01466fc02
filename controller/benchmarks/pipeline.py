"""`servoface bench pipeline`: whole control frames per second vs the wire limit and the stock SDK, and
where the time goes.

One frame = `Pipeline.step`: muscle model (AU frame -> actuator targets) + calibration (targets -> goals) +
twin gate (verdict) + `Driver.cycle` (one Sync Write of the head's goals, a Sync Read of every servo's
Present Position, due slow telemetry, the fault policy). The bus is the in-process emulator at 1 Mbps with
wire time on and Return Delay Time 0.

The chain: the built-in human head's servos (30 now) plus 3 spare XL330-M288 that the driver also
configures and reads every frame (the head never sends them goals). So one frame writes the head's goals and
reads every position; the wire limit is that traffic's wire time (`servoface.hardware.wire`). Three loops on
the same chain, interleaved (`interleave`): the plain stock-SDK loop with the same traffic (re-sending the
goals the pipeline last sent, so the head does not move), the pipeline stepped plainly (stages in series),
and the pipeline with the next frame computed while this frame's replies are on the wire (`Pipeline.step(...,
next_frame=)`). One motion runs through all pipeline windows: the shipped human performance sampled at 50
Hz, back to back, so the gate sees real motion (clips included). Rates are medians of windows, ratios are
medians of per-round ratios to the stock loop; the best window and the machine's load are in the notes.
The driver's clock runs only in the pipeline's windows (`interleave.OwnClock`), so its slow telemetry keeps
the schedule of one continuous back-to-back run (floor-rate reads included) rather than catching up after
each pause. Last: the controller's CPU at 50 Hz over a pty with the emulator in another process (`cpu`).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Iterator

from servoface.controller.benchmarks.cpu import cpu_budget_figures
from servoface.controller.benchmarks.figure import Figure
from servoface.controller.benchmarks.interleave import OwnClock, interleaved, load_text
from servoface.controller.pipeline import FrameTrace

HEAD = "human"
N_SPARE = 3
BAUD = 1_000_000
RETURN_DELAY_US = 0
RATE_HZ = 50.0
GATE_GOAL_MS = 1.0
STAGES = ("muscle_ms", "calibration_ms", "gate_ms", "bus_ms", "total_ms")
STOCK = "stock SDK loop (same traffic)"
SETTLE = 3  # untimed frames per window, every loop alike (see `interleave.interleaved`)
PLAIN = "pipeline frames/s"
AHEAD = "pipeline frames/s, next frame during the wait"


def wire_limit_hz(n_goals: int, n_read: int, baud: int, return_delay_us: float = 0.0) -> tuple[float, int]:
    """(cycles/s, bytes) of one Sync Write of ``n_goals`` goals + Sync Read of ``n_read`` positions."""
    from servoface.hardware.wire import (
        BITS_PER_BYTE,
        status_bytes,
        sync_read_instruction_bytes,
        sync_write_bytes,
    )

    n_bytes = sync_write_bytes(n_goals, 4) + sync_read_instruction_bytes(n_read) + n_read * status_bytes(4)
    wire_s = n_bytes * BITS_PER_BYTE / baud + n_read * return_delay_us * 1e-6
    return 1.0 / wire_s, n_bytes


def _median(values: list[float]) -> float:
    return float(statistics.median(values)) if values else float("nan")


def run(quick: bool = False) -> Iterator[Figure]:
    from servoface.controller.face import head_calibration
    from servoface.controller.head_servos import servo_specs, temperature_limits_c
    from servoface.controller.pipeline import Pipeline
    from servoface.controller.script import SCRIPTS_DIR, load_script
    from servoface.hardware.bus import open_bus
    from servoface.hardware.driver import Driver
    from servoface.hardware.emulator import ServoChain
    from servoface.hardware.servo_config import ServoSpec
    from servoface.hardware.stock_loop import StockSdkLoop
    from servoface.sim.heads import load_head

    head = load_head(HEAD)
    cal = head_calibration(head)
    specs = servo_specs(head, cal, return_delay_us=RETURN_DELAY_US)
    first_spare = max(s.servo_id for s in specs) + 1
    spares = [
        ServoSpec(sid, "XL330-M288", role=f"spare_{sid}", return_delay_us=RETURN_DELAY_US)
        for sid in range(first_spare, first_spare + N_SPARE)
    ]
    all_specs = specs + spares
    n_head, n_all = len(specs), len(all_specs)
    chain = ServoChain.create([(s.servo_id, s.model) for s in all_specs], baud=BAUD, wire_time=True)
    for s in specs:
        chain.servo(s.servo_id).move_by_hand(cal.by_id(s.servo_id).neutral_tick)
    bus = open_bus("dynamixel", port=chain, baud=BAUD)
    stock_bus = open_bus("dynamixel", port=chain, baud=BAUD)
    t0 = time.perf_counter()
    try:
        # the stock loop's plain Sync Read traffic, like for like; the driver's telemetry schedule on the time
        # the pipeline has the bus (`interleave.OwnClock`): its windows join up into one back-to-back run
        driver_clock = OwnClock()
        driver = Driver(bus, all_specs, fast_sync_read=False, clock=driver_clock)
        driver.configure()
        driver.torque_on()
        pipeline = Pipeline(head, cal, driver=driver, rate_hz=RATE_HZ, temperature_limits_c=temperature_limits_c(specs))
        snapshot = driver.read_state()
        pipeline.pin_to({sid: p for sid, p in snapshot.positions_tick().items() if sid in cal.ids})
        pipeline.last_snapshot = snapshot
        open_s = time.perf_counter() - t0
        stock = StockSdkLoop(stock_bus, [s.servo_id for s in specs], [s.servo_id for s in all_specs])
        script = load_script(SCRIPTS_DIR / "human_performance.toml")
        n_loop = int(script.end_s * RATE_HZ)
        frames = [script.sample(k / RATE_HZ) for k in range(n_loop)]
        traces: dict[str, list[FrameTrace]] = {PLAIN: [], AHEAD: []}
        at = [0]  # one motion through every window, whoever steps it

        def plain(_: int) -> None:
            traces[PLAIN].append(pipeline.step(frames[at[0] % n_loop]))
            at[0] += 1

        def ahead(_: int) -> None:
            k = at[0]
            traces[AHEAD].append(pipeline.step(frames[k % n_loop], next_frame=frames[(k + 1) % n_loop]))
            at[0] += 1

        def reference(_: int) -> None:  # the goals the pipeline last sent: the head does not move
            stock.cycle(pipeline.last_goals_tick)

        for k in range(5):  # warm caches (first solves, first reads)
            plain(k)
        traces[PLAIN].clear()
        stats0 = bus.stats.copy()
        rounds, window_s = (3, 0.15) if quick else (16, 0.25)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        windows = interleaved(
            {STOCK: reference, PLAIN: plain, AHEAD: ahead},
            STOCK,
            rounds,
            window_s,
            warm=0,
            settle=SETTLE,
            clocks={PLAIN: driver_clock, AHEAD: driver_clock},
        )
        wall_s = time.perf_counter() - wall0
        cpu_share = (time.process_time() - cpu0) / wall_s
        stats = bus.stats
        timeouts, corrupt = stats.timeouts - stats0.timeouts, stats.corrupt - stats0.corrupt
        bytes_written = stats.bytes_written - stats0.bytes_written
    finally:
        bus.close()
        stock_bus.close()
        chain.close()
    load = load_text()
    limit_hz, limit_bytes = wire_limit_hz(n_head, n_all, BAUD, RETURN_DELAY_US)
    wire_ms = 1e3 / limit_hz
    tag = f"{HEAD} {n_head} servos + {N_SPARE} spare @{BAUD // 1_000_000}M"
    all_traces = traces[PLAIN] + traces[AHEAD]
    verdicts = {k: sum(t.verdict == k for t in all_traces) for k in ("accept", "clip", "reject")}
    used = sum("ahead_ms" in t.timings_ms for t in traces[AHEAD])
    for name in (STOCK, PLAIN, AHEAD):
        st = windows[name]
        unit = "cycles/s" if name == STOCK else "frames/s"
        extra = ""
        if name == AHEAD:
            extra = (f"; the next frame's speculative gate verdict was used on {used} of {len(traces[AHEAD])} "
                     "frames (else checked afresh)")  # fmt: skip
        yield Figure(
            f"{name}, {tag}",
            st.median,
            unit,
            limit=limit_hz,
            goal_ratio=0.9 if name == AHEAD else None,
            note=f"median of {rounds} interleaved {window_s:g} s windows, each after {SETTLE} untimed frames, "
            f"the driver's telemetry on its own clock (best {st.best:.1f}/s = ratio "
            f"{st.best / limit_hz:.3f}); x{st.median_ratio:.3f} the stock SDK loop in the same rounds; wire "
            f"limit = sync write {n_head} goals + sync read {n_all} positions = {limit_bytes} B x 10 bit / "
            f"{BAUD} bps = {wire_ms:.3f} ms{extra}; verdicts {verdicts}; host bytes written "
            f"{bytes_written / max(1, len(all_traces)):.0f}/frame; timeouts {timeouts}, corrupt {corrupt}; "
            f"on-CPU share {cpu_share:.2f}; {load}",
        )
        if name != STOCK:
            yield Figure(
                f"{name} vs stock SDK loop, {tag}",
                st.median_ratio,
                "x SDK loop",
                limit=1.0,
                goal_ratio=0.9 if name == AHEAD else None,
                note=f"frames/s over the stock SDK loop's cycles/s (same traffic: {n_head} goals written, "
                f"{n_all} positions read), median of {rounds} per-round ratios; best round "
                f"x{max(st.ratios, default=0):.3f}; {load}",
            )
    yield from _stage_figures(traces, wire_ms)
    yield Figure(
        "pipeline open (configure + torque on + gate build)",
        open_s * 1e3,
        "ms",
        better="lower",
        note=f"Driver.configure/torque_on of {n_all} servos + Pipeline (TwinGate: TSS tables from the cache)",
    )
    yield from cpu_budget_figures(quick)


def _stage_figures(traces: dict[str, list[FrameTrace]], wire_ms: float) -> Iterator[Figure]:
    plain = traces[PLAIN]
    stage = {name: _median([t.timings_ms[name] for t in plain]) for name in STAGES}
    yield Figure(
        f"pipeline frame time vs the {RATE_HZ:g} Hz frame period ({PLAIN})",
        stage["total_ms"],
        "ms",
        limit=1e3 / RATE_HZ,
        better="lower",
        note="median Pipeline.step wall time; the fixed-rate loop needs it under the frame period",
    )
    limits = {"gate_ms": GATE_GOAL_MS, "bus_ms": wire_ms}
    notes = {
        "muscle_ms": "FaceModel.solve (AU frame -> actuator targets)",
        "calibration_ms": "clamp targets into the calibrated range + targets_to_goals",
        "gate_ms": f"TwinGate.check (goal {GATE_GOAL_MS:g} ms)",
        "bus_ms": "Driver.cycle: sync write + sync read + due telemetry + policy (limit = wire time of the "
        "write + position read)",
        "total_ms": "whole frame",
    }
    for name in STAGES:
        yield Figure(
            f"pipeline stage median {name[:-3]}",
            stage[name],
            "ms",
            limit=limits.get(name),
            better="lower",
            note=f"{notes[name]}; median of {len(plain)} plainly stepped frames (stages in series)",
        )
    ahead = traces[AHEAD]
    if ahead:
        serial = _median([t.timings_ms["total_ms"] for t in ahead])
        overlapped = _median([t.timings_ms.get("ahead_ms", 0.0) for t in ahead])
        yield Figure(
            "pipeline frame time median, next frame computed during the wait",
            serial,
            "ms",
            limit=wire_ms,
            better="lower",
            note=f"median Pipeline.step(next_frame=) wall time; median {overlapped:.3f} ms of muscle + "
            f"calibration + gate per frame ran while the previous frame's replies were on the wire; "
            f"median of {len(ahead)} frames",
        )
    for label, kinds in (("accepted", ("accept",)), ("clipped or rejected", ("clip", "reject"))):
        gate_ms = [t.timings_ms["gate_ms"] for t in plain + ahead if t.verdict in kinds]
        if gate_ms:
            yield Figure(
                f"pipeline gate median, {label} frames",
                _median(gate_ms),
                "ms",
                limit=GATE_GOAL_MS,
                better="lower",
                note=f"TwinGate.check on the {len(gate_ms)} {label} frames (a failing request is scaled "
                "back: several candidate commands re-checked)",
            )
