"""The fixed-rate loop against a fake clock: schedule, skipped (not queued) frames, late/overrun counts."""

from __future__ import annotations

import pytest
from servoface.controller.errors import LoopError
from servoface.controller.loop import FixedRateLoop, Tick
from servoface.controller.timeline import Expression, Movement, Timeline


class FakeClock:
    """Monotonic time that only moves when someone sleeps or does 'work'."""

    def __init__(self, start: float = 1000.0) -> None:
        self.now = start
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, dt: float) -> None:
        self.sleeps.append(dt)
        self.now += dt


def make_loop(clock: FakeClock, work: dict[int, float] | None = None, rate_hz: float = 50.0, **kw):
    ticks: list[Tick] = []

    def callback(tick: Tick) -> None:
        ticks.append(tick)
        clock.now += (work or {}).get(tick.index, 0.002)

    return FixedRateLoop(callback, rate_hz, clock=clock, sleep=clock.sleep, **kw), ticks


def test_frames_land_on_the_schedule() -> None:
    clock = FakeClock()
    loop, ticks = make_loop(clock)
    stats = loop.run(max_frames=100)
    assert stats.frames == 100 and stats.missed == 0 and stats.late == 0 and stats.overruns == 0
    assert [t.index for t in ticks] == list(range(100))
    assert [t.t_s for t in ticks] == pytest.approx([k * 0.02 for k in range(100)])
    assert all(t.late_s == pytest.approx(0.0, abs=1e-9) for t in ticks)
    assert stats.achieved_hz == pytest.approx(50.0, rel=0.02)
    assert stats.jitter_s == pytest.approx(0.0, abs=1e-9)


def test_a_slow_frame_skips_missed_frames_instead_of_queueing_them() -> None:
    clock = FakeClock()
    loop, ticks = make_loop(clock, work={10: 0.065})  # frame 10 takes 65 ms: slots 11 and 12 pass
    stats = loop.run(duration_s=1.0)
    indices = [t.index for t in ticks]
    assert 11 not in indices and 12 not in indices and 13 in indices
    assert stats.missed == 2 and stats.overruns == 1
    assert stats.frames + stats.missed == 50
    t13 = ticks[indices.index(13)]
    assert t13.missed_before == 2 and t13.t_s == pytest.approx(0.26)  # sampled at its own time, not lagged
    assert t13.late_s == pytest.approx(0.005)


def test_late_frames_are_counted() -> None:
    clock = FakeClock()
    loop, ticks = make_loop(clock, work={3: 0.028}, late_after_s=0.002)
    stats = loop.run(max_frames=10)
    # frame 3 ends 8 ms into frame 4's slot: frame 4 runs 8 ms late (not skipped), then the loop catches up
    assert stats.missed == 0 and stats.late == 1
    assert ticks[4].late_s == pytest.approx(0.008)
    assert ticks[5].late_s == pytest.approx(0.0, abs=1e-9)
    assert stats.lateness_s.max == pytest.approx(0.008)
    assert stats.percentile_lateness_s(100) == pytest.approx(0.008)
    assert stats.jitter_s > 0


def test_stop_from_the_callback_and_by_return_value() -> None:
    clock = FakeClock()
    holder: dict[str, FixedRateLoop] = {}

    def callback(tick: Tick) -> None:
        clock.now += 0.001
        if tick.index == 7:
            holder["loop"].stop()

    loop = FixedRateLoop(callback, 100.0, clock=clock, sleep=clock.sleep)
    holder["loop"] = loop
    assert loop.run().frames == 8

    loop2 = FixedRateLoop(lambda tick: tick.index < 4, 100.0, clock=clock, sleep=clock.sleep)
    assert loop2.run().frames == 5


def test_stop_from_another_thread_is_honoured_while_sleeping() -> None:
    clock = FakeClock()
    loop = FixedRateLoop(lambda tick: None, 1.0, clock=clock, sleep=lambda dt: (clock.sleep(dt), loop.stop()))
    stats = loop.run()
    assert stats.frames == 1  # the first frame runs at once, then the stop lands during the wait
    assert max(clock.sleeps) <= loop.max_sleep_s  # sleeps are sliced so a stop is noticed promptly


def test_stage_timings_hook() -> None:
    clock = FakeClock()

    def callback(tick: Tick) -> None:
        with tick.stage("solve"):
            clock.now += 0.003
        with tick.stage("gate"):
            clock.now += 0.001

    stats = FixedRateLoop(callback, 50.0, clock=clock, sleep=clock.sleep).run(max_frames=5)
    assert stats.stages_s["solve"].mean == pytest.approx(0.003)
    assert stats.stages_s["gate"].max == pytest.approx(0.001)
    assert stats.summary()["stages_mean_ms"] == {"solve": 3.0, "gate": 1.0}


def test_loop_drives_a_timeline_on_time_even_when_frames_are_skipped() -> None:
    tl = Timeline("human")
    tl.play(Expression("smile", 1.0, (Movement({"AU12": 1.0}, 1.0),)).clip(), 0.0)
    clock = FakeClock()
    seen: dict[int, float] = {}

    def callback(tick: Tick) -> None:
        seen[tick.index] = tl.sample(tick.t_s).get("AU12")
        clock.now += 0.05 if tick.index == 20 else 0.001

    FixedRateLoop(callback, 50.0, clock=clock, sleep=clock.sleep).run(duration_s=1.0)
    # frame 20 ends at ~0.451 s: slot 21 (0.42 s) has passed and is skipped, frame 22 (0.44 s) runs late
    assert 21 not in seen
    assert seen[22] == pytest.approx(22 * 0.02)  # sampled at its own time: the keyframes stay on time
    assert seen[49] == pytest.approx(0.98)


def test_bad_configuration_and_double_run() -> None:
    with pytest.raises(LoopError, match="rate_hz"):
        FixedRateLoop(lambda t: None, 0.0)
    with pytest.raises(LoopError, match="rate_hz"):
        FixedRateLoop(lambda t: None, float("nan"))
    clock = FakeClock()
    inner: list[Exception] = []

    def callback(tick: Tick) -> bool:
        try:
            loop.run(max_frames=1)
        except LoopError as err:
            inner.append(err)
        return False

    loop = FixedRateLoop(callback, 50.0, clock=clock, sleep=clock.sleep)
    loop.run()
    assert inner and "already running" in str(inner[0])


def test_real_clock_smoke() -> None:
    """Runs on the real monotonic clock; asserts only counts, never wall time."""
    indices: list[int] = []
    loop = FixedRateLoop(lambda tick: indices.append(tick.index), 200.0)
    stats = loop.run(max_frames=3)
    assert stats.frames == 3 and len(indices) == 3
    assert indices == sorted(set(indices)) and indices[-1] == 2 + stats.missed


def test_ctrl_c_stops_cleanly_inside_stop_on_sigint() -> None:
    import os
    import signal

    from servoface.controller.loop import stop_on_sigint

    clock = FakeClock()

    def callback(tick: Tick) -> None:
        clock.now += 0.001
        if tick.index == 3:
            os.kill(os.getpid(), signal.SIGINT)

    loop = FixedRateLoop(callback, 50.0, clock=clock, sleep=clock.sleep)
    before = signal.getsignal(signal.SIGINT)
    with stop_on_sigint(loop):
        stats = loop.run(max_frames=100)
    assert 4 <= stats.frames < 100  # stopped within a frame or so of the signal, no KeyboardInterrupt
    assert signal.getsignal(signal.SIGINT) is before  # handler restored
