"""The head service ends in the one stop path (controller/safe_stop.py) however it ends: its shutdown, a
stop signal under installed StopSignals (the CLI's), a second signal (hurry), a start-up interrupted before
torque-on. Checked on the emulated chain's side: every servo's own torque state, the last goal on the wire."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator

import pytest
from servoface.controller.face import Face
from servoface.controller.service import Status, open_head
from servoface.controller.stop_signals import StopRequested, StopSignals

from tests.controller.service.conftest import start_service


@pytest.fixture
def signals() -> Iterator[StopSignals]:
    """StopSignals installed as the CLI does (main thread); ``request`` is what a handler does."""
    assert threading.current_thread() is threading.main_thread()
    with StopSignals() as installed:
        yield installed


def _all_torque_off(chain: object) -> bool:
    return all(not chain.servo(s).torque_on for s in chain.ids)  # type: ignore[attr-defined]


def _near_neutral(pipeline: object, tolerance_tick: int = 2) -> bool:
    neutral = pipeline.calibration.neutral_goals()  # type: ignore[attr-defined]
    goals = pipeline.last_goals_tick  # type: ignore[attr-defined]
    return max(abs(goals[s] - neutral[s]) for s in neutral) <= tolerance_tick


def test_a_stop_signal_stops_the_loop_which_eases_and_turns_every_torque_off(signals: StopSignals) -> None:
    running = start_service()
    svc, chain = running.service, running.chain
    try:
        playing = svc.express("surprise", transition_s=0.3, hold_s=30.0, track="face")
        first = svc.wait_frame(-1, timeout_s=10.0)
        assert first is not None and svc.wait_frame(first.index + 10, timeout_s=10.0) is not None  # moving
        signals.request(signal.SIGTERM)  # what the handler does on `kill`
        svc._thread.join(30.0)  # noqa: SLF001 - the loop stops by itself, nobody called shutdown
        assert not svc.running
        report = svc.report
        assert report is not None and report.reason == "SIGTERM"
        assert report.eased and report.safe and not report.unreached, report
        assert _all_torque_off(chain)
        assert _near_neutral(running.pipeline)
        assert playing.wait(1.0).final and playing.status is not Status.DONE  # cut by the stop
        assert svc.shutdown() is report  # a later shutdown returns the same report
    finally:
        running.close()


def test_a_second_signal_hurries_to_neutral_then_torque_off_never_mid_pose(signals: StopSignals) -> None:
    running = start_service()
    svc, chain = running.service, running.chain
    try:
        assert svc.express("surprise", transition_s=0.2, hold_s=0.0, track="face").wait(5.0) is Status.DONE
        assert svc.wait_settled(svc.last_trace.index, timeout_s=5.0)  # type: ignore[union-attr]
        with svc.paused_loop():  # both signals land before the loop's next frame
            signals.request(signal.SIGINT)
            signals.request(signal.SIGINT)
        svc._thread.join(30.0)  # noqa: SLF001
        report = svc.report
        assert report is not None and report.reason == "SIGINT"
        assert report.eased and "second stop signal" in report.ease_note, report
        assert "(hurried by a second stop signal)" in report.lines()[0]
        assert report.safe and _all_torque_off(chain)
        assert _near_neutral(running.pipeline)  # at neutral when torque went off: nothing dropped mid-pose
    finally:
        running.close()


def test_hurry_goes_straight_to_neutral_within_the_gate_caps() -> None:
    """The hurried stop is the fastest the gate allows — and no faster: every goal decoded on the wire
    during it is within the limits and the per-frame speed cap."""
    from tests.integration.wire_checks import check_wire

    running = start_service()
    svc, chain = running.service, running.chain
    try:
        assert svc.express("surprise", transition_s=0.2, hold_s=0.0, track="face").wait(5.0) is Status.DONE
        start = len(chain.goal_writes())
        svc.hurry()  # a second Ctrl-C before the first one's easing
        report = svc.shutdown(ease_s=0.8)
        assert report.eased and report.ease_note == "hurried by a second stop signal", report
        assert report.safe and _all_torque_off(chain) and _near_neutral(running.pipeline)
        assert check_wire(running.pipeline, chain, start) > 0
    finally:
        running.close()


def test_face_close_returns_the_stop_report() -> None:
    with Face.open("human", emulate=True, wire_time=False) as face:
        face.express("happiness", transition_s=0.2, hold_s=0.0)
        chain = face.chain
        report = face.close(reason="end")
    assert report is not None and report is face.stop_report
    assert report.reason == "end" and report.eased and report.safe and report.clean
    assert report.lines()[0].startswith("stop (end): eased to neutral") and "on every servo" in report.lines()[0]
    assert _all_torque_off(chain)
    assert face.close() is report  # twice: the same report


def test_face_close_without_any_motion_goes_down_the_same_path() -> None:
    face = Face.open("human", emulate=True, wire_time=False)
    chain = face.chain
    report = face.close(ease_s=0.0, reason="end")
    assert report is not None and report.safe and not report.eased and report.ease_note == "not asked"
    assert _all_torque_off(chain)


def test_a_signal_before_torque_on_ends_the_start_up(signals: StopSignals) -> None:
    """(The wire side — torque never on — is checked over the pty: test_safe_stops_pty.py.)"""
    signals.request(signal.SIGINT)  # Ctrl-C while loading: open raises before switching torque on
    with pytest.raises(StopRequested):
        open_head("human", emulate=True, wire_time=False)
