"""The app-level heartbeat (controller/studio/liveness.py): a browser whose socket stays open but goes
silent (a dead network, a frozen tab) counts as gone; the head eases to neutral unless hold. Read from the
emulator. No wall-time asserts: the 1 s figure is `servoface bench studio`'s."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from servoface.controller.studio.liveness import HEARTBEAT_INTERVAL_S, Liveness

from tests.studio.conftest import StudioRig


@contextmanager
def beating(ws: Any) -> Iterator[None]:
    """Heartbeats every 0.25 s for the block (as the page sends them), then silence."""
    stop = threading.Event()

    def run() -> None:
        while not stop.is_set():
            ws.send(json.dumps({"type": "heartbeat"}))
            stop.wait(HEARTBEAT_INTERVAL_S)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def _neutral(rig: StudioRig) -> dict[int, int]:
    rig.wait_for(lambda: rig.service.last_trace is not None, what="a first frame")
    return dict(rig.service.last_trace.goals_sent)  # type: ignore[union-attr]


def _state(rig: StudioRig) -> dict[str, Any]:
    return dict(rig.client.get("/api/state").json())


def test_a_silent_browser_with_its_socket_open_eases_the_head_to_neutral(studio: StudioRig) -> None:
    neutral = _neutral(studio)
    with studio.connect() as ws:
        with beating(ws):
            ws.send(json.dumps({"type": "set_aus", "aus": {"AU26": 0.8, "AU12": 0.6}, "transition_s": 0.1}))
            held = lambda: studio.service.status().tracks["studio"].state == "holding"  # noqa: E731
            studio.wait_for(lambda: studio.goals() != neutral and held(), what="the pose")
            assert _state(studio)["silent_clients"] == 0
        # silence from here on; the socket stays open (the client still answers the server's pings)
        studio.wait_for(lambda: studio.goals() == neutral, what="the emulated servos back at neutral")
        state = _state(studio)
        assert state["clients"] == 1 and state["silent_clients"] == 1
        assert state["last_drop_reason"] == "silent"
        # speaking again makes the socket live again but moves nothing by itself
        with beating(ws):
            studio.wait_for(lambda: _state(studio)["silent_clients"] == 0, what="the socket live again")
            frame = studio.service.last_trace.index  # type: ignore[union-attr]
            studio.wait_for(lambda: studio.service.last_trace.index > frame + 10, what="frames")  # type: ignore[union-attr]
            assert studio.goals() == neutral
            ws.send(json.dumps({"type": "set_aus", "aus": {"AU26": 0.8}, "transition_s": 0.1}))  # the user acts
            studio.wait_for(lambda: studio.goals() != neutral, what="the head moving again on a user action")


def test_hold_keeps_the_pose_when_the_browser_goes_silent(studio: StudioRig) -> None:
    neutral = _neutral(studio)
    with studio.connect() as ws:
        with beating(ws):
            ws.send(json.dumps({"type": "hold", "hold": True}))
            ws.send(json.dumps({"type": "set_aus", "aus": {"AU26": 0.8}, "transition_s": 0.0}))
            studio.wait_for(lambda: _state(studio)["hold"], what="hold on")
            seen: list[tuple[int, dict[int, int]]] = []

            def settled() -> bool:
                index, goals = studio.service.last_trace.index, studio.goals()  # type: ignore[union-attr]
                seen.append((index, goals))
                earlier = [g for i, g in seen if i <= index - 10]
                return goals != neutral and bool(earlier) and earlier[-1] == goals

            studio.wait_for(settled, what="the pose on the wire, settled")
            posed = seen[-1][1]
        studio.wait_for(lambda: _state(studio)["silent_clients"] == 1, what="the silence noticed")
        frame = studio.service.last_trace.index  # type: ignore[union-attr]
        studio.wait_for(lambda: studio.service.last_trace.index > frame + 25, what="half a second of frames")  # type: ignore[union-attr]
        assert studio.goals() == posed


def test_a_socket_that_never_sent_a_heartbeat_is_judged_by_its_close() -> None:
    """Scripts and older clients: no heartbeat, no silence watch. Manual clock: no timing in the test."""
    now = [0.0]
    gone: list[str] = []
    live = Liveness(gone.append, timeout_s=1.0, clock=lambda: now[0], watch=False)
    try:
        quiet, beater = live.joined(), live.joined()
        live.heard(beater, heartbeat=True)
        now[0] = 5.0
        assert not live.check() and live.silent == 1 and live.live == 1  # the quiet one is still live
        live.left(quiet)
        assert gone == ["closed"]
        b2 = live.joined()
        live.heard(b2, heartbeat=True)
        live.heard(b2, busy=+1)  # a message being handled for longer than the timeout is not silence
        now[0] = 10.0
        assert not live.check()
        live.heard(b2, busy=-1)
        now[0] = 11.5
        assert live.check() and gone == ["closed", "silent"]
        live.left(b2)  # already counted as gone: no second drop
        live.left(beater)
        assert gone == ["closed", "silent"]
    finally:
        live.close()


def test_time_the_server_did_not_run_is_not_silence() -> None:
    """The watchdog woke late (the studio's process descheduled or starved on a loaded machine): heartbeats
    may be unread in the socket buffers, so that time is excused; silence afterwards is still found within
    the timeout of the time the process ran. A wake less than `STALL_S` late excuses nothing. Manual
    clock, one watchdog wake per `watch_step`."""
    from servoface.controller.studio.liveness import EXCUSE_LIMIT, STALL_S, WATCH_PERIOD_S

    now = [0.0]
    gone: list[str] = []
    live = Liveness(gone.append, timeout_s=0.8, clock=lambda: now[0], watch=False)

    def run_until_gone(last: float, n: int) -> float:  # the process runs on, the browser says nothing
        while len(gone) < n and now[0] < 10.0:
            now[0] += WATCH_PERIOD_S
            last = live.watch_step(last)
        return now[0]

    try:
        key = live.joined()
        live.heard(key, heartbeat=True)
        now[0] = 0.6
        last = live.watch_step(0.0)  # woke 0.55 s late: excused (the socket was last heard at 0)
        assert gone == [] and live.live == 1
        silent_at = run_until_gone(last, 1)
        assert gone == ["silent"]
        assert 0.55 + 0.8 < silent_at <= 0.55 + 0.8 + WATCH_PERIOD_S + 1e-9, silent_at  # (without: at 0.8)
        heard_at = now[0]
        live.heard(key, heartbeat=True)  # speaks again: live, nothing moves by itself
        assert live.live == 1
        now[0] += WATCH_PERIOD_S + 0.9 * STALL_S  # a wake a little late only
        last = live.watch_step(heard_at)
        silent_at = run_until_gone(last, 2)
        assert gone == ["silent", "silent"]
        assert silent_at - heard_at < 0.8 + 0.9 * STALL_S, silent_at - heard_at  # nothing was excused
        # a machine so loaded that every wake is 0.3 s late: a dead browser is still found, once the excuse
        # limit is spent (2 timeouts), ~0.8 s after that
        heard_at = now[0]
        live.heard(key, heartbeat=True)
        last = now[0]
        while len(gone) < 3 and now[0] < heard_at + 10.0:
            now[0] += WATCH_PERIOD_S + 0.3
            last = live.watch_step(last)
        assert gone == ["silent"] * 3
        assert 0.8 + EXCUSE_LIMIT * 0.8 <= now[0] - heard_at <= 0.8 + EXCUSE_LIMIT * 0.8 + 0.35 + 1e-9, now[0]
    finally:
        live.close()
