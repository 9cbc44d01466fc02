"""A node speaks as every other front end does (a real Zenoh session on loopback, in this process; the
emulator's side of the wire): ``cmd/say`` through `schedule_speech` (the head's jaw budget, the sound on
the head's output), ``cmd/play`` of a shipped script with a say cue through script_play."""

from __future__ import annotations

import time
from typing import Any

import pytest
from servoface.controller.network.client import HeadsClient
from servoface.controller.network.keys import head_keys
from servoface.controller.network.node import HeadNode, needs_synthesis
from servoface.controller.network.testbed import free_port
from servoface.controller.network.zconfig import open_session
from servoface.controller.service import HeadService, open_head

pytestmark = pytest.mark.slow


def test_a_speaking_shipped_script_is_played_on_the_slow_worker() -> None:
    assert needs_synthesis("play", {"name": "human_hello"})
    assert not needs_synthesis("play", {"name": "human_performance"})
    assert needs_synthesis("cue", {"what": {"verb": "play", "name": "human_hello"}})
    assert not needs_synthesis("cue", {"what": {"verb": "cue", "what": {"verb": "say"}}})


def _wait(cond: Any, timeout_s: float = 20.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while not (value := cond()) and time.monotonic() < deadline:
        time.sleep(0.05)
    return value


def test_node_say_and_a_speaking_script_go_through_the_speech_path(monkeypatch: pytest.MonkeyPatch) -> None:
    from servoface.controller.speech.say import jaw_budget_for

    calls: list[Any] = []
    real = HeadService.speak

    def speak(self: HeadService, what: Any, *, at_s: float | None = None, duration_s: float | None = None) -> Any:
        handle = real(self, what, at_s=at_s, duration_s=duration_s)
        calls.append(what)  # after: the utterance is through the jaw account when the test sees it
        return handle

    monkeypatch.setattr(HeadService, "speak", speak)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    opened = open_head("human", emulate=True, wire_time=False)
    service = HeadService(opened.head, opened.pipeline)
    keys = head_keys("lobby", "talker")
    node_session = open_session(listen=[endpoint])
    node = HeadNode(service, node_session, keys).start()
    client_session = open_session(connect=[endpoint])
    try:
        client = HeadsClient(client_session)
        assert _wait(lambda: client.status(keys, timeout_s=1.0)), "the node never answered"
        jaw = opened.head.servo_ids["jaw"]

        def jaw_talked() -> bool:  # on the wire, since the log was last cleared
            goals = [g for _, sid, g in opened.chain.goal_writes() if sid == jaw]
            return bool(goals) and max(goals) - min(goals) > 20

        opened.chain.log.clear()
        client.send(keys, "say", text="Hello over the network.")
        assert _wait(lambda: len(calls) >= 1), "cmd/say never reached HeadService.speak"
        assert calls[0].clock.name == "monotonic"  # the sound path (no sound card here)
        assert jaw_budget_for(service).account > 0, "the utterance did not go through the jaw account"
        assert _wait(jaw_talked), "the jaw did not talk on the wire"
        assert _wait(lambda: service.status().tracks["speech"].state == "empty")
        opened.chain.log.clear()
        client.send(keys, "play", name="human_hello")
        assert _wait(lambda: len(calls) >= 2), "the say cue of the shipped script was not spoken"
        assert _wait(lambda: service.status().tracks["face"].state != "empty")
        assert _wait(jaw_talked), "the shipped script's say cue did not move the jaw on the wire"
    finally:
        node.close()
        client_session.close()
        node_session.close()
        service.shutdown(ease_s=0.0)
        opened.chain.close()
