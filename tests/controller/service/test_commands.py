"""Commands: validated in the caller's thread (a bad one raises at once and changes nothing), callable
from many threads, scheduled on the service clock, ended by the safe stop."""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import pytest
from servoface.controller.errors import ControllerError
from servoface.controller.service import HeadService, ServiceClosedError, Status

from tests.controller.service.conftest import Running, start_service

BAD: list[tuple[str, Any, str]] = [
    ("unknown AU", lambda s: s.set_aus({"AU99": 0.5}), "AU99"),
    ("AU above 1", lambda s: s.set_aus({"AU12": 1.5}), "AU12"),
    ("non-finite AU", lambda s: s.set_aus({"AU12": math.nan}), "AU12"),
    ("negative transition", lambda s: s.set_aus({"AU12": 0.3}, transition_s=-1), "transition_s"),
    ("unknown track", lambda s: s.set_aus({"AU12": 0.3}, track="mouth"), "track"),
    ("start time nan", lambda s: s.set_aus({"AU12": 0.3}, at_s=math.nan), "at_s"),
    ("start time text", lambda s: s.express("happiness", at_s="soon"), "at_s"),
    ("unknown expression", lambda s: s.express("glee"), "glee"),
    ("intensity above 1", lambda s: s.express("happiness", intensity=2), "intensity"),
    ("missing script", lambda s: s.play("/nonexistent/script.toml"), "script.toml"),
    ("dog script", lambda s: s.play("dog_performance"), "dog"),
    ("not playable", lambda s: s.play(42), "play"),
    ("bad then", lambda s: s.play("human_performance", then="loop"), "then"),
    ("bad duration", lambda s: s.play("human_performance", duration_s=0), "duration_s"),
    ("look_at two numbers", lambda s: s.look_at((1.0, 2.0)), "point_mm"),
    ("look_at nan", lambda s: s.look_at((math.nan, 0.0, 500.0)), "point_mm"),
    ("follow a number", lambda s: s.follow(3), "follow"),
    ("stop unknown track", lambda s: s.stop("mouth"), "track"),
    ("negative release", lambda s: s.stop("face", release_s=-1), "release_s"),
    ("alive not a bool", lambda s: s.set_alive(blink="yes"), "blink"),
    ("clear unknown AU", lambda s: s.clear_aus(["AU99"]), "AU99"),
]


@pytest.fixture(scope="module")
def shared() -> Any:
    r = start_service()
    yield r
    r.close()


@pytest.mark.parametrize("what,call,named", BAD, ids=[b[0] for b in BAD])
def test_a_bad_command_raises_at_once_and_changes_nothing(shared: Running, what: str, call: Any, named: str) -> None:
    svc: HeadService = shared.service
    before = svc.status().tracks
    inbox = len(svc._inbox)
    with pytest.raises(ControllerError) as err:
        call(svc)
    assert named in str(err.value), f"{what}: {err.value}"
    assert len(svc._inbox) == inbox and svc.status().tracks == before


def test_a_finished_command_is_done_once_its_last_frame_is_published(
    running: Running, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A waiter woken by DONE reads the frame the command finished on (its status view and trace), not the
    one before: the handle is completed after `_publish` (it once was before, in `advance`)."""
    svc = running.service
    real = HeadService._publish
    watched: list[Any] = []
    at_publish: list[tuple[float, Status]] = []

    def publish(self: HeadService, t_s: float, tick: Any, trace: Any) -> None:
        if watched:
            at_publish.append((t_s, watched[0].status))
        real(self, t_s, tick, trace)

    monkeypatch.setattr(HeadService, "_publish", publish)
    h = svc.set_aus({"AU1": 0.5}, track="face", transition_s=0.2)
    watched.append(h)
    assert h.wait(5.0) is Status.DONE
    last = svc.last_trace
    assert last is not None and h.finished_s is not None and last.t_s >= h.finished_s
    finishing = [status for t_s, status in at_publish if t_s == h.finished_s]
    assert finishing == [Status.RUNNING], at_publish[-3:]  # published first, then completed


def test_a_command_starts_at_its_absolute_time_on_the_service_clock(running: Running) -> None:
    svc = running.service
    at = svc.now_s() + 2.0  # far enough that a loaded machine's loop shows it scheduled before it starts
    h = svc.set_aus({"AU1": 0.5}, track="face", transition_s=0.1, at_s=at)
    deadline = time.monotonic() + 1.5  # the status view shows it once a frame has taken it from the inbox
    while svc.status().tracks["face"].scheduled != 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert h.status is Status.PENDING and svc.status().tracks["face"].scheduled == 1
    assert h.wait(5.0) is Status.DONE
    assert h.started_s == pytest.approx(at)
    assert h.finished_s is not None and h.finished_s >= at + 0.1 - 1e-9


def test_commands_from_many_threads_all_complete(running: Running) -> None:
    svc = running.service
    handles = []
    lock = threading.Lock()

    def worker(k: int) -> None:
        for i in range(15):
            h = svc.set_aus({f"AU{[1, 2, 4, 12][k]}": 0.1 + 0.02 * i}, track="studio", merge=True, transition_s=0.0)
            with lock:
                handles.append(h)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(h.wait(5.0).final for h in handles)
    assert svc.wait_settled(timeout_s=5.0)
    final = svc.wait_frame(svc.last_trace.index)
    assert final is not None
    for au in ("AU1", "AU2", "AU4", "AU12"):  # merge=True: every thread's last value stays
        assert final.aus[au] == pytest.approx(0.1 + 0.02 * 14)


def test_stop_release_and_hold(running: Running) -> None:
    svc = running.service
    h = svc.set_aus({"AU2": 0.6}, track="face", transition_s=2.0)
    h.wait(0.4)
    frozen = svc.stop("face", hold=True)
    assert frozen.wait(2.0) is Status.DONE and h.status is Status.CANCELLED
    held = svc.status().tracks["face"].aus["AU2"]
    assert 0.0 < held < 0.6
    assert svc.wait_frame(svc.last_trace.index + 5).aus["AU2"] == pytest.approx(held)
    assert svc.stop("face", release_s=0.2).wait(3.0) is Status.DONE
    assert svc.status().tracks["face"].state == "empty"


def test_shutdown_eases_to_neutral_turns_torque_off_and_refuses_more() -> None:
    running = start_service()
    svc, chain = running.service, running.chain
    try:
        assert svc.express("surprise", transition_s=0.2, hold_s=0.0).wait(5.0) is Status.DONE
        report = svc.shutdown(ease_s=0.4)
        assert report.eased and report.torque_off and not report.unreached
        assert all(not chain.servo(s).torque_on for s in chain.ids)
        neutral = running.pipeline.calibration.neutral_goals()
        assert max(abs(running.pipeline.last_goals_tick[s] - neutral[s]) for s in neutral) <= 2
        with pytest.raises(ServiceClosedError):
            svc.set_aus({"AU12": 0.3})
        assert svc.shutdown() == report  # twice is fine
    finally:
        chain.close()


def test_alive_layers_blink_on_their_track(running: Running) -> None:
    svc = running.service
    assert svc.set_alive(blink=True, idle=True, seed=8).wait(2.0) is Status.DONE
    sub = svc.subscribe("trace", maxlen=1000)
    svc.wait_frame(svc.last_trace.index + 250, timeout_s=15.0)  # 5 s; seed 8 blinks at 2.2 s
    aus = [t.aus for t in sub.drain()]
    assert any(a.get("AU45", 0.0) > 0.5 for a in aus)
    assert any(abs(a.get("AU51", 0.0)) + abs(a.get("AU52", 0.0)) > 1e-4 for a in aus)  # idle head motion
    assert svc.set_alive(blink=False, idle=False).wait(2.0) is Status.DONE


def test_torque_off_clears_the_tracks_and_torque_on_pins_first(running: Running) -> None:
    from servoface.controller.service import ServiceError

    svc, chain = running.service, running.chain
    assert svc.set_aus({"AU12": 0.4}, track="face", transition_s=0.1).wait(5.0) is Status.DONE
    assert svc.torque_off().wait(2.0) is Status.DONE
    assert all(not chain.servo(s).torque_on for s in chain.ids)
    assert svc.status().tracks["face"].state == "empty"
    with pytest.raises(ServiceError, match="torque is off"):
        svc.set_aus({"AU12": 0.4})
    writes, frames = len(chain.goal_writes()), svc.status().frames
    assert svc.wait_frame(svc.last_trace.index, timeout_s=0.2) is None  # limp: no frames through the gate
    assert len(chain.goal_writes()) == writes  # no goals while limp ...
    assert svc.status().frames > frames and svc.telemetry() is not None  # ... but telemetry goes on
    assert svc.torque_on().wait(2.0) is Status.DONE
    assert all(chain.servo(s).torque_on for s in chain.ids)
    assert svc.set_aus({"AU12": 0.4}, track="face", transition_s=0.1).wait(5.0) is Status.DONE


def test_shutdown_async_returns_a_handle() -> None:
    running = start_service()
    try:
        handle = running.service.shutdown_async(ease_s=0.2)
        assert handle.wait(15.0) is Status.DONE and running.service.report is not None
        assert all(not running.chain.servo(s).torque_on for s in running.chain.ids)
    finally:
        running.chain.close()
