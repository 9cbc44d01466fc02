"""A pose the head's own face model refuses (here AU12 limited to 0.5 by the profile's AU table) never
leaves a command hanging with torque on. `express` and `set_aus` refuse it at once (ServiceError naming the
AU and the range, nothing scheduled), and so does `play` of a script, timeline or clip (each of its
expressions solved on the head first). A source only the frame finds it in (a caller's own source object)
fails its command in that frame (its waiter is told) and its track is left empty; the service sends the
last safe goals again in that frame (the bus and every servo's Bus Watchdog kept fed) and plays on. It used
to raise in every frame: the command never ended, nothing was sent, and a waiter waited for ever."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from servoface.controller.frame import AUFrame
from servoface.controller.service import HeadService, ServiceError, Status, open_head

from tests.controller.service.conftest import Running
from tests.human_copy import NARROW_AU12, narrow_au_copy

LIMIT = NARROW_AU12


@pytest.fixture(scope="module")
def narrow(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built-in human profile with its AU table limiting AU12 to 0.5."""
    folder = narrow_au_copy(tmp_path_factory.mktemp("narrow") / "narrow_au")
    script = folder / "smile.toml"
    script.write_text('[script]\nface = "human"\n\n[[play]]\nat_s = 0.0\nlibrary = "happiness"\n')
    return folder


@pytest.fixture
def running(narrow: Path) -> Iterator[Running]:
    opened = open_head(narrow, emulate=True, wire_time=False)
    r = Running(opened, HeadService(opened.head, opened.pipeline))
    yield r
    r.close()


def _goals(r: Running) -> dict[int, int]:
    return {sid: r.chain.servo(sid).read_register("Goal Position") for sid in r.pipeline.last_goals_tick}


def test_express_and_set_aus_refuse_what_the_head_refuses_at_once(running: Running) -> None:
    svc = running.service
    before = svc.status().tracks
    with pytest.raises(ServiceError) as err:
        svc.express("happiness")
    assert "expression 'happiness'" in str(err.value) and "on head 'narrow_au'" in str(err.value)
    assert "AU12" in str(err.value) and LIMIT in str(err.value), err.value
    with pytest.raises(ServiceError, match=r"set_aus, on head 'narrow_au': AU12: expected"):
        svc.set_aus({"AU12": 0.8})
    assert svc.status().tracks == before
    assert svc.express("happiness", intensity=0.4).wait(5.0) is Status.DONE  # what it takes still plays


def test_play_refuses_a_script_timeline_or_clip_the_head_cannot_show_at_once(running: Running, narrow: Path) -> None:
    """As `express`: the script's every expression is solved on the head before the command is placed (it
    used to be found in the first frame, with the command already running)."""
    from servoface.controller.script import load_script
    from servoface.controller.service.sources import transition_clip

    svc = running.service
    before = svc.status().tracks
    path = narrow / "smile.toml"
    with pytest.raises(ServiceError) as err:
        svc.play(str(path))
    assert str(err.value).startswith(f"play: {path}: expression 'happiness' (track face), on head 'narrow_au': AU12")
    assert LIMIT in str(err.value), err.value
    with pytest.raises(ServiceError, match=r"play: timeline: expression 'happiness' \(track face\).*AU12"):
        svc.play(load_script(path, library=None).timeline)
    with pytest.raises(ServiceError, match=r"play: clip 'beam': expression 'beam', on head 'narrow_au': AU12"):
        svc.play(transition_clip({"AU12": 0.8}, 0.5, 0.0, name="beam"))
    assert svc.status().tracks == before  # nothing placed
    assert svc.play(transition_clip({"AU12": 0.5}, 0.3, 0.0, name="half")).wait(5.0) is Status.DONE


class _Source:
    """A caller's own source (`sample` and `duration_s`, not a `Recording`): only its frames say what it
    plays, so only the frame can refuse it."""

    face_type = "human"
    duration_s = 1.0

    def sample(self, t_s: float) -> AUFrame:
        return AUFrame(t_s, {"AU12": 0.8}, "human")


def test_a_source_the_head_refuses_fails_in_its_frame_and_the_head_holds(running: Running) -> None:
    svc = running.service
    faults = svc.subscribe("fault")
    assert svc.set_aus({"AU1": 0.3}, track="face", transition_s=0.1).wait(5.0) is Status.DONE
    held = _goals(running)
    handle = svc.play(_Source())
    assert handle.wait(5.0) is Status.FAILED, handle.status  # told, not left waiting
    assert handle.detail.startswith("track 'face' (")  # which command's track, and its source
    assert "AU12" in handle.detail and LIMIT in handle.detail, handle.detail
    events = [e for e in faults.drain() if e.kind == "frame_error"]
    assert events and "AU12" in events[0].detail
    time.sleep(0.3)  # three Bus Watchdog periods (0.1 s): it trips if the bus went quiet
    assert svc.running
    assert svc.wait_settled(timeout_s=5.0)
    neutral = {s.servo_id: s.neutral_tick for s in running.pipeline.calibration.servos}
    assert any(held[sid] != neutral[sid] for sid in held)  # (the smile's track was not at neutral)
    for sid, tick in _goals(running).items():
        servo = running.chain.servo(sid)
        assert not servo._watchdog_tripped, sid
        # the failed command's track is left empty: the face goes where the other tracks say (none: neutral),
        # at the gate's rates, like any command that ends
        assert abs(tick - neutral[sid]) <= 1, (sid, tick, neutral[sid])
    assert svc.set_aus({"AU1": 0.0}, track="face", transition_s=0.1).wait(5.0) is Status.DONE  # plays on


def test_face_express_names_the_expression_the_head_refuses(narrow: Path) -> None:
    """The Python API says which expression, at what intensity, on which head, and why; nothing moves."""
    from servoface.controller.errors import ControllerError
    from servoface.controller.face import Face

    face = Face.open(narrow, emulate=True)
    try:
        before = dict(face.pipeline.last_goals_tick)
        with pytest.raises(ControllerError) as err:
            face.express("happiness")
        assert str(err.value).startswith("express: expression 'happiness' at intensity 1, on head 'narrow_au': AU12")
        assert LIMIT in str(err.value)
        assert face.pipeline.last_goals_tick == before
        face.express("happiness", intensity=0.4, hold_s=0.1)  # what the head takes still plays
    finally:
        face.close(ease_s=0.0)


class _Stream:
    """A live source whose frames the head refuses until ``good`` is set (AU12 0.8, then 0.3)."""

    face_type = "human"

    def __init__(self) -> None:
        self.good = False

    def sample(self, t_s: float) -> AUFrame:
        return AUFrame(t_s, {"AU12": 0.3 if self.good else 0.8}, "human")


def test_a_stream_the_head_refuses_is_skipped_frame_by_frame_and_the_bus_stays_fed(running: Running) -> None:
    """A live source is not ended by a refused value (a stream message out of the head's range drops that
    frame, as the README says of a bad message): its command keeps running, and every refused frame sends the
    last safe goals again. Without that, nothing is written while the values stay refused, and each servo's
    Bus Watchdog (0.1 s) stops it until the driver re-arms it after the pause."""
    svc = running.service
    faults = svc.subscribe("fault")
    driver = running.pipeline.driver
    assert driver is not None
    goal_write_bytes = 14 + 5 * len(running.pipeline.last_goals_tick)  # one Sync Write of every goal (4 bytes each)
    stream = _Stream()
    handle = svc.follow(stream)
    time.sleep(0.1)  # the stream has begun: its frames are refused from here on
    before = driver.bus.stats.bytes_written
    time.sleep(0.4)
    refused = len([e for e in faults.drain() if e.kind == "frame_error"])
    written = driver.bus.stats.bytes_written - before
    assert handle.status is Status.RUNNING, handle.detail
    assert refused >= 10  # refused frame after frame
    # each refused frame sent the last safe goals again (without it: no goal write at all in that time)
    assert written >= (refused - 5) * goal_write_bytes, (written, refused)
    for sid in running.pipeline.last_goals_tick:
        assert not running.chain.servo(sid)._watchdog_tripped, sid
    stream.good = True
    assert svc.wait_frame(timeout_s=2.0) is not None
    time.sleep(0.2)
    trace = svc.last_trace
    assert trace is not None and trace.aus.get("AU12") == pytest.approx(0.3)  # plays on once the values fit
    svc.stop("stream").wait(2.0)
