"""Tracks mixed per AU by the documented rules: max / clamped sum / override, on the emulated head."""

from __future__ import annotations

import json
import time

import pytest
from servoface.controller.inputs import MessageDecoder, StreamSource
from servoface.controller.script import parse_script
from servoface.controller.service import Status

from tests.controller.service.conftest import Running

SCRIPT = """
[script]
face = "human"
title = "hold a pose"
end_s = 3.0

[poses]
look = { AU1 = 0.3, AU12 = 0.6, AU51 = 0.2 }

[expressions.look]
duration_s = 3.0
movements = [{ pose = "look", percent = 10, easing = "min_jerk" }, { pose = "look", percent = 90 }]

[[play]]
at_s = 0.0
expression = "look"
"""


def _stream(aus: dict[str, float]) -> StreamSource:
    source = StreamSource(MessageDecoder("human"), smoothing=None, dropout_ms=60_000.0)
    assert source.feed(json.dumps({"t": 0.0, "aus": aus}))
    return source


def test_script_on_face_and_stream_on_gaze_blend_as_documented(running: Running) -> None:
    """face: AU1 0.3, AU12 0.6, AU51 0.2; gaze (live stream): AU12 0.2, AU51 0.1, AU61 0.3.
    Documented: AU12 max -> 0.6; AU51 head turn is summed -> 0.3; AU1 and AU61 pass through."""
    svc = running.service
    script = parse_script(SCRIPT)
    follow = svc.follow(_stream({"AU12": 0.2, "AU51": 0.1, "AU61": 0.3}), track="gaze")
    play = svc.play(script, track="face")
    sub = svc.subscribe("trace", maxlen=1000)
    assert play.wait(10.0) is Status.DONE
    assert follow.status is Status.RUNNING  # the stream plays on
    traces = [t for t in sub.drain() if t.t_s >= play.started_s + 1.0]  # the script holds its pose there
    assert traces
    for trace in traces:
        assert trace.aus["AU12"] == pytest.approx(0.6)
        assert trace.aus["AU51"] == pytest.approx(0.3)
        assert trace.aus["AU1"] == pytest.approx(0.3)
        assert trace.aus["AU61"] == pytest.approx(0.3)
    deadline = time.monotonic() + 5.0  # the status view is refreshed by the loop, a frame after the handle
    while svc.status().tracks["face"].state != "holding" and time.monotonic() < deadline:
        time.sleep(0.02)
    view = svc.status().tracks
    assert view["face"].state == "holding" and view["gaze"].state == "running"
    # what went on the wire is the gate's answer to that mix, frame for frame
    n = len(running.head.actuators)
    tail = {sid: tick for _, sid, tick in running.chain.goal_writes()[-n:]}
    assert tail == svc.last_trace.goals_sent


def test_a_slider_on_the_studio_track_overrides_an_expression_on_its_aus_only(running: Running) -> None:
    svc = running.service
    expr = svc.express("happiness", transition_s=0.2, hold_s=0.1)
    assert expr.wait(5.0) is Status.DONE
    apex = dict(svc.last_trace.aus)
    assert apex["AU12"] > 0.5 and len(apex) >= 2
    slider = svc.set_aus({"AU12": 0.1}, track="studio", transition_s=0.1)
    assert slider.wait(5.0) is Status.DONE
    frame = svc.wait_frame(svc.last_trace.index)
    assert frame is not None
    assert frame.aus["AU12"] == pytest.approx(0.1)  # lower than the expression: max would have kept 0.8
    for au, value in apex.items():
        if au != "AU12":
            assert frame.aus.get(au, 0.0) == pytest.approx(value), au
    assert svc.status().tracks["face"].command_id == expr.id  # the expression still holds underneath
    cleared = svc.clear_aus(track="studio", transition_s=0.1)
    assert cleared.wait(5.0) is Status.DONE
    back = svc.wait_frame(svc.last_trace.index)
    assert back is not None and back.aus["AU12"] == pytest.approx(apex["AU12"])


def test_a_newer_command_on_a_track_takes_over_from_where_it_is(running: Running) -> None:
    svc = running.service
    first = svc.set_aus({"AU2": 0.8}, track="face", transition_s=1.0)
    first.wait(0.3)
    second = svc.set_aus({"AU4": 0.4}, track="face", transition_s=0.2)
    assert second.wait(5.0) is Status.DONE and first.status is Status.CANCELLED
    assert "taken over" in first.detail
    assert svc.last_trace.aus.get("AU2", 0.0) == pytest.approx(0.0, abs=1e-9)
    assert svc.last_trace.aus["AU4"] == pytest.approx(0.4)


def test_speech_owns_the_mouth_while_an_expression_holds_the_rest(running: Running) -> None:
    from servoface.controller.timeline import ChannelClip, Key

    svc = running.service
    assert svc.express("happiness", transition_s=0.2, hold_s=0.0).wait(5.0) is Status.DONE
    apex = dict(svc.last_trace.aus)
    assert apex.get("AU25", 0.0) > 0.0  # the smile parts the lips
    viseme = ChannelClip({"AU25": (Key(0.0, 0.05), Key(0.6, 0.05)), "AU26": (Key(0.0, 0.3), Key(0.6, 0.3))}, 0.6)
    sub = svc.subscribe("trace", maxlen=200)
    spoken = svc.speak(viseme)
    assert spoken.wait(5.0) is Status.DONE
    during = [t for t in sub.drain() if spoken.started_s + 0.05 <= t.t_s <= spoken.finished_s - 0.05]
    assert during
    for trace in during:  # override: the speech track's AU25 wins (lower than the smile's), AU26 is its own
        assert trace.aus["AU25"] == pytest.approx(0.05) and trace.aus["AU26"] == pytest.approx(0.3)
        for au, value in apex.items():
            if au not in ("AU25", "AU26"):
                assert trace.aus.get(au, 0.0) == pytest.approx(value), au
    after = svc.wait_frame(svc.last_trace.index + 2)
    assert after is not None and after.aus["AU25"] == pytest.approx(apex["AU25"])  # released at its end


def test_a_gaze_target_sums_with_a_head_turn_on_the_face_track(running: Running) -> None:
    svc = running.service
    assert svc.set_aus({"AU51": 0.2, "AU12": 0.3}, track="face", transition_s=0.1).wait(5.0) is Status.DONE
    look = svc.look_at((250.0, 0.0, 600.0))
    assert look.wait(5.0) is Status.DONE
    gaze = svc.status().tracks["gaze"].aus
    frame = svc.wait_frame(svc.last_trace.index)
    assert frame is not None and gaze.get("AU51", 0.0) > 0.0
    assert frame.aus["AU51"] == pytest.approx(min(1.0, 0.2 + gaze["AU51"]))  # sum on head turns
    assert frame.aus["AU61"] == pytest.approx(gaze["AU61"]) and frame.aus["AU12"] == pytest.approx(0.3)
