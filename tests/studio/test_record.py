"""Recording a live tracker stream (real UDP datagrams / TCP lines of AU frames) into keyframes: the head
follows it while it records (read from the emulator), and the keys, played back as a script, give the
AUs that were sent (within the recording's tolerance)."""

from __future__ import annotations

import json
import math
import socket
import time
from typing import Any

import pytest

from tests.studio.conftest import StudioRig

RATE_HZ = 30.0
N = 75  # 2.5 s of a 30 Hz tracker


def _aus(t: float) -> dict[str, float]:
    """A jaw that opens and closes (a ramp up, a hold, a ramp down) and a smile on a slow sine."""
    jaw = min(1.0, t / 0.8) if t < 1.2 else max(0.0, 1.0 - (t - 1.2) / 0.6)
    return {"AU26": round(0.7 * jaw, 4), "AU12": round(0.3 + 0.25 * math.sin(2 * math.pi * t / 2.5), 4)}


class _Sender:
    def __init__(self, transport: str, port: int) -> None:
        self.transport = transport
        if transport == "udp":
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.connect(("127.0.0.1", port))
        else:
            self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)

    def send(self, message: dict[str, Any]) -> None:
        data = json.dumps(message).encode()
        self.sock.sendall(data if self.transport == "udp" else data + b"\n")

    def close(self) -> None:
        self.sock.close()


@pytest.mark.parametrize("transport", ["udp", "tcp"])
def test_a_live_stream_records_into_keys_that_replay_the_same_aus(studio: StudioRig, transport: str) -> None:
    rig = studio
    rig.wait_for(lambda: rig.service.last_trace is not None, what="a first frame")
    neutral = dict(rig.service.last_trace.goals_sent)  # type: ignore[union-attr]
    r = rig.client.post("/api/record/start", json={"transport": transport, "port": 0, "tolerance": 0.01})
    assert r.status_code == 200, r.text
    state = r.json()
    assert state["active"] and state["transport"] == transport and state["port"] > 0
    assert rig.client.post("/api/record/start", json={}).status_code == 409  # one at a time
    recording = rig.server.studio.recording
    sender = _Sender(transport, state["port"])
    moved = False
    try:
        sender.send({"t": 0.1, "aus": {"AU99": 1.0}})  # a bad message: counted, never recorded
        rig.wait_for(lambda: recording.source.stats.bad == 1, what="the bad message counted")
        for i in range(N):
            t = i / RATE_HZ
            sender.send({"t": round(t, 6), "aus": _aus(t)})
            # one at a time: the stream keeps the latest value, so a backlog would be skipped, not recorded
            try:
                rig.wait_for(lambda i=i: len(recording.samples) > i, what=f"sample {i} recorded")
            except AssertionError as err:
                raise AssertionError(f"{err}; stream {recording.source.stats.summary()}") from None
            time.sleep(1.0 / RATE_HZ)  # a tracker's pace: faster would hit the input's rate limit (240/s)
            moved = moved or rig.goals() != neutral
        rig.wait_for(lambda: moved or rig.goals() != neutral, what="the head following the stream")
    finally:
        sender.close()
    assert rig.client.get("/api/record").json()["samples"] == N
    out = rig.client.post("/api/record/stop", json={}).json()
    assert out["samples"] == N and out["bad"] == 1 and out["time_base"] == "sender"
    keys = out["keys"]
    assert keys[0]["t_s"] == 0.0 and keys[-1]["t_s"] == pytest.approx((N - 1) / RATE_HZ, abs=1e-3)
    assert 4 <= len(keys) < N // 2  # reduced: ramps and a hold need few keys, the sine some more
    assert all(set(k["pose"]) == {"AU12", "AU26"} and k["easing"] == "linear" for k in keys)
    # played back as the script format `servoface play` reads: the same AUs at the sent times
    document = {
        "script": {"face": "human", "end_s": keys[-1]["t_s"]},
        "expressions": {"recorded": {"keyframes": keys}},
        "play": [{"at_s": 0.0, "expression": "recorded", "track": "face"}],
    }
    sampled = rig.client.post("/api/scripts/sample", json={"document": document, "fps": RATE_HZ}).json()
    frames = sampled["frames"]
    assert len(frames) >= N - 1
    worst = 0.0
    for frame in frames[: N - 1]:
        sent = _aus(float(frame["t_s"]))
        for name, value in sent.items():
            worst = max(worst, abs(float(frame["aus"].get(name, 0.0)) - value))
    assert worst <= 0.01 + 1e-4, worst
    assert rig.client.post("/api/record/stop", json={}).status_code == 409  # nothing running now


def test_record_refuses_bad_values_and_a_port_in_use(studio_shared: StudioRig) -> None:
    rig = studio_shared
    for body, field in (
        ({"transport": "serial"}, "transport"),
        ({"port": 70000}, "port"),
        ({"tolerance": 0}, "tolerance"),
        ({"follow": "yes"}, "follow"),
    ):
        r = rig.client.post("/api/record/start", json=body)
        assert r.status_code == 422 and r.json()["error"]["field"] == field, r.text
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    try:
        r = rig.client.post("/api/record/start", json={"transport": "udp", "port": busy.getsockname()[1]})
        assert r.status_code == 409 and r.json()["error"]["field"] == "port", r.text
    finally:
        busy.close()
    assert rig.client.get("/api/record").json() == {"active": False}
