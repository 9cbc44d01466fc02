"""Observers: bounded drop-oldest queues at their own rates; a slow or stalled one never delays a frame."""

from __future__ import annotations

import threading
import time

import pytest
from servoface.controller.service import FrameSummary, ServiceError, Status

from tests.controller.service.conftest import Running, start_service


class FakeClock:
    """Loop time that moves only when the loop sleeps: a frame can be late only if the loop itself waits
    on something other than its schedule (an observer would be that something)."""

    def __init__(self) -> None:
        self.t_s = 0.0
        self.lock = threading.Lock()

    def __call__(self) -> float:
        return self.t_s

    def sleep(self, dt_s: float) -> None:
        with self.lock:
            self.t_s += dt_s
        time.sleep(0)  # let other threads run


def test_a_stalled_and_a_slow_observer_do_not_delay_the_loop() -> None:
    clock = FakeClock()
    running = start_service(clock=clock, sleep=clock.sleep)
    try:
        svc = running.service
        stalled = svc.subscribe("trace", maxlen=4)
        slow = svc.subscribe("frame", maxlen=8)
        release = threading.Event()
        got: list[FrameSummary] = []

        def stalled_reader() -> None:  # takes one item, then sits on it until the run is over
            stalled.get(timeout_s=5.0)
            release.wait(30.0)

        def slow_reader() -> None:
            while not release.is_set():
                item = slow.get(timeout_s=0.2)
                if item is not None:
                    got.append(item)
                time.sleep(0.05)

        readers = [threading.Thread(target=stalled_reader), threading.Thread(target=slow_reader)]
        for r in readers:
            r.start()
        handle = svc.express("happiness", transition_s=1.0, hold_s=2.0)  # 150 frames of loop time
        assert handle.wait(60.0) is Status.DONE  # the loop got there although nobody kept up
        release.set()
        for r in readers:
            r.join()
        stats = svc.loop_stats
        assert stats.frames >= 150 and stats.late == 0 and stats.missed == 0
        assert stalled.dropped > 0 and len(stalled) == 4  # full, oldest dropped
        assert slow.dropped > 0 and got and all(a.index < b.index for a, b in zip(got, got[1:], strict=False))
    finally:
        running.close()


def test_an_observer_gets_items_at_its_own_rate(running: Running) -> None:
    svc = running.service
    tenth = svc.subscribe("frame", rate_hz=10.0, maxlen=100)
    every = svc.subscribe("frame", maxlen=100)
    telemetry = svc.subscribe("telemetry", rate_hz=5.0, maxlen=100)
    playback = svc.subscribe("playback", maxlen=100)
    h = svc.set_aus({"AU2": 0.5}, track="face", transition_s=0.5, hold_s=0.5)
    assert h.wait(5.0) is Status.DONE
    slow, fast = tenth.drain(), every.drain()
    # 1 s of frames at 50 Hz; a loaded machine skips some (the loop drops missed frames), so counts are loose:
    # the rate itself is the spacing below
    assert len(fast) >= 20 and 5 <= len(slow) < len(fast)
    times = [f.t_s for f in slow]
    assert all(b - a >= 0.1 - 1e-6 for a, b in zip(times, times[1:], strict=False))
    snaps = telemetry.drain()
    assert snaps and all(s.servos for s in snaps)
    states = [(e.command_id, e.status) for e in playback.drain()]
    assert (h.id, Status.RUNNING) in states and (h.id, Status.DONE) in states


def test_subscribe_validates() -> None:
    running = start_service()
    try:
        with pytest.raises(ServiceError, match="kind"):
            running.service.subscribe("frames")
        with pytest.raises(ServiceError, match="maxlen"):
            running.service.subscribe("frame", maxlen=0)
        with pytest.raises(ServiceError, match="rate_hz"):
            running.service.subscribe("frame", rate_hz=-1)
    finally:
        running.close()
