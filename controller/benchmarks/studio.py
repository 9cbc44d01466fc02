"""`servoface bench studio`: what a person at the studio feels, on the emulated human head (wire time on),
through the real server (uvicorn on a loopback port) and a real WebSocket client.

- ``studio_slider_to_wire_median`` / ``_p95``: a slider event (a ``set_aus`` WebSocket message, transition 0,
  as a drag sends them) from the client's send until the Sync Write carrying the changed goals has fully
  arrived on the emulated wire (the emulator's packet log, its clock). Goal: p95 <= 40 ms.
- ``studio_twin_updates_per_s``: twin images (640x480 PNG, the achievable face) the same client receives
  per second while the head moves (expressions back to back); goal >= 15.
- ``studio_silent_browser_ease_start_s`` / ``_at_neutral_s``: a browser whose socket stays open but goes
  silent (heartbeats every 0.25 s, then none): from its last message (emulator clock) until the first goal
  of the ease to neutral is on the wire (goal <= 1.1 s: the 1 s heartbeat timeout, the watchdog's 50 ms, a
  frame) and until every servo's goal is at neutral (goal <= 1.8 s: + the 0.6 s ease + margin).
"""

from __future__ import annotations

import json
import random
import statistics
import time
from collections.abc import Iterator
from typing import Any

from servoface.controller.benchmarks.figure import Figure

SLIDER_P95_GOAL_MS = 40.0
TWIN_FPS_GOAL = 15.0


def _percentile(values: list[float], q: float) -> float:
    data = sorted(values)
    return data[min(len(data) - 1, max(0, int(round(q / 100.0 * (len(data) - 1)))))]


def _first_change_s(chain: Any, since_s: float, before: dict[int, int]) -> float | None:
    for t, sid, tick in chain.goal_writes():
        if t >= since_s and before.get(sid, tick) != tick:
            return float(t)
    return None


def _wire_goals(chain: Any) -> dict[int, int]:
    out: dict[int, int] = {}
    for _, sid, tick in chain.goal_writes()[-200:]:
        out[sid] = tick
    return out


def _sliders(svc: Any, chain: Any, ws: Any, n: int) -> list[float]:
    rng = random.Random(11)
    out: list[float] = []
    value = 0.0
    for i in range(n):
        svc.wait_settled(timeout_s=3.0)
        svc.wait_frame(svc.last_trace.index + 2)
        before = _wire_goals(chain)
        time.sleep(rng.uniform(0.0, svc.period_s))  # any phase against the frame clock
        value = 0.4 if value == 0.0 else 0.0
        sent_s = chain.time_s
        ws.send(json.dumps({"type": "set_aus", "id": i, "aus": {"AU12": value, "AU2": value}, "transition_s": 0.0}))
        deadline = time.monotonic() + 2.0
        arrived = None
        while arrived is None and time.monotonic() < deadline:
            svc.wait_frame(svc.last_trace.index, timeout_s=0.1)
            arrived = _first_change_s(chain, sent_s, before)
        if arrived is not None:
            out.append(arrived - sent_s)
        _drain(ws, reply_id=i)
    return out


def _drain(ws: Any, reply_id: int) -> None:
    """Read what the server sent (state pushes, the reply): a client that never reads stops answering pings."""
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        try:
            message = ws.recv(timeout=0.5)
        except TimeoutError:
            return
        if isinstance(message, str) and json.loads(message).get("id") == reply_id:
            return


def _twin_rate(svc: Any, ws: Any, seconds: float) -> tuple[float, int]:
    names = ["happiness", "surprise", "anger", "sadness"]
    ws.send(json.dumps({"type": "subscribe", "twin": True, "frames": False, "telemetry": False}))
    images = 0
    start = time.monotonic()
    k = 0
    next_move = start
    while time.monotonic() - start < seconds:
        now = time.monotonic()
        if now >= next_move:  # a new expression every 0.6 s: the head never rests
            svc.express(names[k % len(names)], intensity=0.9, transition_s=0.5, hold_s=0.1)
            k += 1
            next_move = now + 0.6
        try:
            message = ws.recv(timeout=0.2)
        except TimeoutError:
            continue
        if isinstance(message, bytes) and message[:1] == b"A":
            images += 1
    return images / (time.monotonic() - start), images


def _wire_after(chain: Any, since_s: float) -> list[tuple[float, int, int]]:
    return [w for w in chain.goal_writes()[-2000:] if w[0] > since_s]


def _silence_once(svc: Any, chain: Any, url: str, connect: Any) -> tuple[float, float] | None:
    """One silent browser: (last message -> ease starts, last message -> at neutral), emulator clock."""
    import threading

    neutral = svc.pipeline.calibration.neutral_goals()
    last_sent = [0.0]
    stop = threading.Event()
    with connect(url, open_timeout=30, max_size=None, max_queue=None) as ws:
        ws.recv(timeout=30)  # hello
        ws.send(json.dumps({"type": "subscribe", "twin": False, "frames": False, "telemetry": False}))

        def beat() -> None:
            while not stop.is_set():
                ws.send(json.dumps({"type": "heartbeat"}))
                last_sent[0] = chain.time_s
                stop.wait(0.25)

        thread = threading.Thread(target=beat, daemon=True)
        thread.start()
        ws.send(json.dumps({"type": "set_aus", "aus": {"AU26": 0.8, "AU12": 0.6}, "transition_s": 0.1}))
        deadline = time.monotonic() + 20.0
        posed: dict[int, int] = {}
        while time.monotonic() < deadline:  # the pose on the wire, unchanged over 10 frames
            before = _wire_goals(chain)
            svc.wait_frame(svc.last_trace.index + 10, timeout_s=2.0)
            posed = _wire_goals(chain)
            if posed == before and posed != neutral:
                break
        stop.set()
        thread.join()
        t_last = last_sent[0]
        start_s = end_s = None
        deadline = time.monotonic() + 10.0
        while end_s is None and time.monotonic() < deadline:
            svc.wait_frame(svc.last_trace.index, timeout_s=0.1)
            now: dict[int, int] = dict(posed)
            for t, sid, tick in _wire_after(chain, t_last):
                if start_s is None and tick != posed.get(sid, tick):
                    start_s = t
                now[sid] = tick
                if end_s is None and all(now.get(k) == v for k, v in neutral.items()):
                    end_s = t
        if start_s is None or end_s is None:
            return None
        return start_s - t_last, end_s - t_last


def run(quick: bool = False) -> Iterator[Figure]:
    from servoface.controller.service import HeadService, open_head
    from servoface.controller.studio import StudioOptions, StudioServer
    from servoface.controller.studio.security import RateLimiter
    from websockets.sync.client import connect

    opened = open_head("human", emulate=True, wire_time=True)
    svc = HeadService(opened.head, opened.pipeline)
    chain = opened.chain
    server = StudioServer(svc, port=0, options=StudioOptions(render=True), limiter=RateLimiter(1e6, 1e6)).start()
    try:
        url = f"ws://127.0.0.1:{server.port}/api/ws?token={server.token}"
        with connect(url, open_timeout=30, max_size=None, max_queue=None) as ws:
            ws.recv(timeout=30)  # hello
            ws.send(json.dumps({"type": "subscribe", "twin": False, "frames": False, "telemetry": False}))
            ms = [x * 1e3 for x in _sliders(svc, chain, ws, 15 if quick else 60)]
            if ms:
                note = (
                    f"{len(ms)} set_aus WebSocket messages (transition 0), client send -> changed goals' Sync Write "
                    f"arrived (emulator log); frame period {svc.period_s * 1e3:g} ms"
                )
                yield Figure("studio_slider_to_wire_median", statistics.median(ms), "ms", limit=SLIDER_P95_GOAL_MS,
                             better="lower", note=note)  # fmt: skip
                yield Figure(
                    "studio_slider_to_wire_p95", _percentile(ms, 95), "ms", limit=SLIDER_P95_GOAL_MS,
                    goal=SLIDER_P95_GOAL_MS, better="lower", note=f"max {max(ms):.2f} ms; " + note,
                )  # fmt: skip
            renderer = server.studio.renderer
            if renderer is not None and renderer.wait_ready(120) and not renderer.error:
                seconds = 3.0 if quick else 8.0
                fps, count = _twin_rate(svc, ws, seconds)
                yield Figure(
                    "studio_twin_updates_per_s", fps, "images/s", limit=TWIN_FPS_GOAL, goal=TWIN_FPS_GOAL,
                    note=f"{count} achievable-face PNGs (640x480) received over the WebSocket in {seconds:g} s "
                    "while the head moved (expressions back to back); render thread capped at 30/s",
                )  # fmt: skip
        runs = [r for r in (_silence_once(svc, chain, url, connect) for _ in range(2 if quick else 5)) if r]
        if runs:
            note = (
                f"{len(runs)} runs: a WebSocket client sends heartbeats every 0.25 s, then nothing (socket open); "
                "from its last message (emulator clock) to the wire"
            )
            starts, ends = [r[0] for r in runs], [r[1] for r in runs]
            yield Figure(
                "studio_silent_browser_ease_start_s", statistics.median(starts), "s", limit=1.1, better="lower",
                note=f"max {max(starts):.3f} s; {note}: first goal of the ease",
            )  # fmt: skip
            yield Figure(
                "studio_silent_browser_at_neutral_s", statistics.median(ends), "s", limit=1.8, better="lower",
                note=f"max {max(ends):.3f} s; {note}: every goal at neutral",
            )  # fmt: skip
    finally:
        server.stop()
        svc.shutdown(ease_s=0.0)
        chain.close()
