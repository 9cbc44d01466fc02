"""Malformed commands to a `servoface node` process over a real Zenoh session on loopback, checked from its
emulator's side of the wire (the node's `--wire-log`) and from what it publishes on `state/refused`.

Found by exploratory testing: a misspelt key (`intensty`) was ignored and the expression played at full
intensity; a `look_at` with a number for `point_mm` was refused as "'int' object is not iterable"; a `play`
of a 300-character name crashed Zenoh's callback (a traceback on the node's stderr, no refusal, not counted).
Now each is refused with the field named, counted, and nothing reaches the wire."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
from servoface.controller.network.keys import head_keys
from servoface.controller.network.messages import envelope, open_envelope
from servoface.controller.network.testbed import NodeProc, start_nodes
from servoface.controller.network.zconfig import open_session
from servoface.sim.heads import load_head

pytestmark = pytest.mark.slow

HEAD = load_head("human")
BROW = HEAD.servo_ids["brow_inner_l"]
CHEEK = HEAD.servo_ids["lip_corner_l"]
KEYS = head_keys("lobby", "m1")


@pytest.fixture(scope="module")
def node(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[NodeProc, Any, list[dict[str, Any]]]]:
    (proc,) = start_nodes(tmp_path_factory.mktemp("zenoh"), ["m1"])
    session = open_session(connect=[proc.endpoint])
    refused: list[dict[str, Any]] = []
    sub = session.declare_subscriber(
        KEYS.state("refused"), lambda s: refused.append(open_envelope(s.payload.to_bytes())[1])
    )
    try:
        assert proc.wait_goals(BROW), proc.log.read_text()[-2000:]
        yield proc, session, refused
    finally:
        sub.undeclare()
        session.close()
        proc.stop()


def _send(session: Any, refused: list[dict[str, Any]], verb: str, body: dict[str, Any], seq: int) -> dict[str, Any]:
    """Put one command until the node answers it on state/refused (a put before the routes exist is lost)."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        n = len(refused)
        session.put(KEYS.cmd(verb), envelope(body, seq))
        seq += 1_001  # newer than anything before, also after a put that was lost
        for _ in range(20):
            if len(refused) > n:
                return refused[n]
            time.sleep(0.05)
    raise AssertionError(f"no refusal of {verb} {body}")


@pytest.mark.parametrize(
    ("verb", "body", "named"),
    [
        ("express", {"name": "happiness", "intensty": 0.1}, "express.intensty: unknown key; expected name, intensity"),
        ("say", {"text": "hello", "voice": "en-gb"}, "say.voice: unknown key; expected text"),
        ("look_at", {"point_mm": 5}, "look_at.point_mm: expected [x, y, z] in mm or null, got 5"),
        ("play", {"name": "x" * 300}, "expression 'xxxx"),
        ("cue", {"what": {"verb": "express", "name": "happiness", "bogus": 1}, "at_s": 1e308}, "at_s 1e+308 is"),
    ],
    ids=["misspelt-key", "say-voice", "look_at-number", "long-name", "cue-far"],
)
def test_a_malformed_command_is_refused_by_name_and_moves_nothing(
    node: tuple[NodeProc, Any, list[dict[str, Any]]], verb: str, body: dict[str, Any], named: str
) -> None:
    proc, session, refused = node
    since = time.monotonic()
    answer = _send(session, refused, verb, body, seq=int(since * 1000))
    assert answer["verb"] == verb and named in answer["error"], answer
    assert len(answer["error"]) <= 300 and "1000000000000000000" not in answer["error"]
    time.sleep(1.0)  # a frame or fifty: an express that slipped through would have moved brow and cheek
    for sid in (BROW, CHEEK):
        goals = {g for _, g in proc.goals(sid, since_s=since - 0.5)}
        assert len(goals) <= 1, (sid, sorted(goals))
    log = proc.log.read_text()
    assert "Traceback" not in log and "callback error" not in log, log[-3000:]
