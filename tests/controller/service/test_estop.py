"""E-stop from another thread: torque off on every servo within two frames, decoded from the emulator's
side of the wire (packet log and the servos' own torque state); latched until cleared."""

from __future__ import annotations

import threading

import pytest
from servoface.controller.service import EStopLatchedError, Status

from tests.controller.service.conftest import Running, start_service

TORQUE_ENABLE = 64  # control table address (1 byte)


@pytest.mark.parametrize("wire_time", [False, True], ids=["instant-wire", "wire-time"])
def test_estop_from_another_thread_turns_torque_off_within_two_frames(wire_time: bool) -> None:
    running: Running = start_service(wire_time=wire_time)
    try:
        svc, chain = running.service, running.chain
        ids = set(chain.ids)
        playing = svc.express("surprise", transition_s=2.0, hold_s=5.0)
        assert svc.wait_frame(svc.wait_frame(-1).index + 5) is not None  # it is moving
        asked_at: list[float] = []
        handles = []

        def press() -> None:
            asked_at.append(chain.time_s)
            handles.append(svc.estop("test button"))

        presser = threading.Thread(target=press)
        presser.start()
        presser.join()
        assert handles[0].wait(2.0) is Status.DONE
        t0 = asked_at[0]
        offs = [(t, sid) for t, sid, v in chain.register_writes(TORQUE_ENABLE, 1, signed=False) if v == 0 and t >= t0]
        assert {sid for _, sid in offs} == ids  # every servo got Torque Enable = 0 on the wire
        assert all(not chain.servo(sid).torque_on for sid in ids)
        t_off = max(t for t, _ in offs)
        # frames (goal Sync Writes) between the button and the last torque-off: at most the one in flight
        frames_between = {t for t, _, _ in chain.goal_writes() if t0 <= t <= t_off}
        assert len(frames_between) <= 1, frames_between
        assert not [t for t, _, _ in chain.goal_writes() if t > t_off]  # no goal after the stop
        assert playing.status is Status.CANCELLED and svc.estop_latched
        # latched: motion and torque-on are refused until cleared; nothing reaches the wire
        n_log = len(chain.goal_writes())
        with pytest.raises(EStopLatchedError):
            svc.set_aus({"AU12": 0.3})
        with pytest.raises(EStopLatchedError):
            svc.torque_on()
        assert svc.wait_frame(svc.last_trace.index, timeout_s=0.2) is None  # limp: frames go on, no goals
        assert len(chain.goal_writes()) == n_log and all(not chain.servo(s).torque_on for s in ids)
        # cleared, then torque on: goals pinned to where the servos are, motion allowed again
        assert svc.clear_estop().wait(2.0) is Status.DONE
        assert svc.torque_on().wait(2.0) is Status.DONE
        assert all(chain.servo(s).torque_on for s in ids)
        assert svc.set_aus({"AU12": 0.3}, track="face", transition_s=0.1).wait(5.0) is Status.DONE
    finally:
        running.close()


def test_estop_twice_is_one_latch_and_shutdown_after_it_skips_the_ease(running: Running) -> None:
    svc = running.service
    a = svc.estop()
    b = svc.estop()
    assert a.wait(2.0) is Status.DONE and (b is a or b.wait(2.0) is Status.DONE)
    report = svc.shutdown(ease_s=0.5)
    assert report.torque_off and not report.eased
    assert all(not running.chain.servo(s).torque_on for s in running.chain.ids)


def test_the_estop_event_names_the_presses_it_answers(running: Running) -> None:
    """One event per torque-off, naming each press's reason once ("torque off; torque off" named none)."""
    svc = running.service
    events = svc.subscribe("fault")
    a, b = svc.estop("studio button"), svc.estop("studio button")
    assert a.wait(2.0) is Status.DONE and b.wait(2.0) is Status.DONE
    later = svc.estop("network")
    assert later.wait(2.0) is Status.DONE
    details = [e.detail for e in events.drain() if e.kind == "estop"]
    assert details[0] == "torque off (studio button)", details
    assert details[-1] == "torque off (network)", details
    events.close()
