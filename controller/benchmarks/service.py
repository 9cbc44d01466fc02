"""`servoface bench service`: what a front end waits for, on the emulated human head (wire time on).

- ``service_command_to_wire_median`` / ``_p99``: a slider-style ``set_aus`` (transition 0, on the studio
  track) from ``submit`` until the Sync Write that carries the changed goals has fully arrived on the
  emulated wire (the emulator's packet log, its clock). The loop runs at fixed frames, so a command waits
  for the next frame (up to one period), then that frame's muscle model, gate and Sync Write. Goal: p99
  <= one frame period + one cycle (the median bus time of one driver cycle: Sync Write, Sync Read,
  telemetry), measured in the same run.
- ``service_estop_to_torque_off_median``: ``estop()`` from another thread until the last servo's Torque
  Enable = 0 is on the wire; goal <= two frame periods.
- ``service_late_frames_with_stalled_observer``: late frames over a stretch of motion with an observer
  that never reads, next to the same stretch without it (a slow observer must not add late frames).
"""

from __future__ import annotations

import random
import statistics
import threading
import time
from collections.abc import Iterator
from typing import Any

from servoface.controller.benchmarks.figure import Figure

TORQUE_ENABLE = 64


def _percentile(values: list[float], q: float) -> float:
    data = sorted(values)
    k = min(len(data) - 1, max(0, int(round(q / 100.0 * (len(data) - 1)))))
    return data[k]


def _goal_frames(chain: Any, since_s: float) -> list[tuple[float, dict[int, int]]]:
    frames: dict[float, dict[int, int]] = {}
    for t, sid, tick in chain.goal_writes():
        if t >= since_s:
            frames.setdefault(t, {})[sid] = tick
    return sorted(frames.items())


def _first_change_s(chain: Any, submit_s: float, before: dict[int, int]) -> float | None:
    for t, goals in _goal_frames(chain, submit_s):
        if any(before.get(sid) != tick for sid, tick in goals.items()):
            return t
    return None


def _latency(svc: Any, chain: Any, n: int) -> tuple[list[float], list[float]]:
    from servoface.controller.service import Status

    rng = random.Random(7)
    latencies: list[float] = []
    bus_ms: list[float] = []
    value = 0.0
    for _ in range(n):
        assert svc.wait_settled(timeout_s=3.0)
        svc.wait_frame(svc.last_trace.index + 2)  # two more frames at rest: the wire repeats one goal set
        last = _goal_frames(chain, chain.time_s - 0.2)
        before = dict(last[-1][1]) if last else {}
        time.sleep(rng.uniform(0.0, svc.period_s))  # any phase against the frame clock
        value = 0.35 if value == 0.0 else 0.0
        submit_s = chain.time_s
        handle = svc.set_aus({"AU12": value, "AU2": value}, track="studio", transition_s=0.0)
        if handle.wait(2.0) is not Status.DONE:
            continue
        svc.wait_frame(svc.last_trace.index + 1)
        arrived = _first_change_s(chain, submit_s, before)
        if arrived is not None:
            latencies.append(arrived - submit_s)
        if svc.last_trace is not None:
            bus_ms.append(svc.last_trace.timings_ms.get("bus_ms", 0.0))
    return latencies, bus_ms


def _one_estop(svc: Any, chain: Any) -> float | None:
    svc.express("surprise", transition_s=1.5, hold_s=2.0)
    svc.wait_frame(svc.wait_frame(-1).index + 10 + random.randrange(5))
    asked: list[float] = []
    handles: list[Any] = []

    def press() -> None:
        asked.append(chain.time_s)
        handles.append(svc.estop("bench"))

    presser = threading.Thread(target=press)
    presser.start()
    presser.join()
    handles[0].wait(2.0)
    offs = [t for t, _, v in chain.register_writes(TORQUE_ENABLE, 1, signed=False) if v == 0 and t >= asked[0]]
    return max(offs) - asked[0] if len(offs) >= len(chain.ids) else None


def _estop(quick: bool) -> list[float]:
    from servoface.controller.service import HeadService, open_head

    out: list[float] = []
    for _ in range(2 if quick else 5):
        opened = open_head("human", emulate=True, wire_time=True)
        svc = HeadService(opened.head, opened.pipeline)
        try:
            took = _one_estop(svc, opened.chain)
            if took is not None:
                out.append(took)
        finally:
            svc.shutdown(ease_s=0.0)
            opened.chain.close()
    return out


def _late_frames(svc: Any, stalled: bool, seconds: float) -> int:
    from servoface.controller.service import Status

    sub = svc.subscribe("trace", maxlen=8) if stalled else None
    before = svc.loop_stats.late
    handle = svc.express("happiness", transition_s=seconds / 2, hold_s=seconds / 2)
    handle.wait(seconds + 5.0)
    late = svc.loop_stats.late - before
    if sub is not None:
        sub.close()
    back = svc.neutral(0.3)
    back.wait(3.0)
    assert back.status is Status.DONE
    return int(late)


def run(quick: bool = False) -> Iterator[Figure]:
    from servoface.controller.service import HeadService, open_head

    opened = open_head("human", emulate=True, wire_time=True)
    svc = HeadService(opened.head, opened.pipeline)
    chain = opened.chain
    try:
        period_ms = svc.period_s * 1e3
        latencies, bus_ms = _latency(svc, chain, 12 if quick else 60)
        cycle_ms = statistics.median(bus_ms) if bus_ms else 0.0
        limit = period_ms + cycle_ms
        ms = [x * 1e3 for x in latencies]
        note = (
            f"{len(ms)} set_aus on the studio track, submit -> changed goals' Sync Write arrived (emulator log); "
            f"limit = frame period {period_ms:g} ms + one cycle {cycle_ms:.2f} ms (median bus time per frame)"
        )
        if ms:
            yield Figure("service_command_to_wire_median", statistics.median(ms), "ms", limit=limit, better="lower",
                         note=note)  # fmt: skip
            yield Figure(
                "service_command_to_wire_p99", _percentile(ms, 99), "ms", limit=limit, goal=limit, better="lower",
                note=f"max {max(ms):.2f} ms; " + note,
            )  # fmt: skip
        seconds = 1.0 if quick else 3.0
        base = _late_frames(svc, False, seconds)
        stalled = _late_frames(svc, True, seconds)
        yield Figure(
            "service_late_frames_with_stalled_observer", float(stalled), "frames", limit=float(max(base, 1)),
            better="lower", goal=float(base + max(2, base)),
            note=f"{seconds:g} s of motion at {svc.rate_hz:g} Hz with an observer that never reads; "
            f"{base} late without it (a late frame: started > period/4 after due; machine load counts too)",
        )  # fmt: skip
    finally:
        svc.shutdown(ease_s=0.0)
        chain.close()
    stops = [x * 1e3 for x in _estop(quick)]
    if stops:
        yield Figure(
            "service_estop_to_torque_off_median", statistics.median(stops), "ms", limit=2 * period_ms,
            better="lower", note=f"max {max(stops):.2f} ms over {len(stops)} e-stops from another thread, "
            "until every servo's Torque Enable = 0 has arrived (emulator log); limit two frame periods",
        )  # fmt: skip
