"""Fuzzing the studio over real sockets: SERVOFACE_FUZZ_EXAMPLES (default 10^4) requests and WebSocket
messages in all, mutated from valid bodies or made of weird values, against one studio on the emulated
head. Every answer is a 2xx or a clear 4xx (status, code, message, field); never a 5xx, never a dropped
socket. Then the wire, read from the emulator's packet log: no Goal Position outside the servo's limits."""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.fuzz.strategies import mutate, paths, values, weird_text
from tests.studio.conftest import StudioRig, _close, _open

# The studio's uvicorn thread pings its WebSockets every WS_PING_INTERVAL_S with a payload from the global
# `random` (uvicorn's websockets_sansio_impl / wsproto_impl); when a ping falls inside a draw, Hypothesis
# sees the global state change and blames the strategy. Our strategies use no `random`.
pytestmark = pytest.mark.filterwarnings("ignore:Do not use the `random` module inside strategies")

TOTAL = int(os.environ.get("SERVOFACE_FUZZ_EXAMPLES", "10000"))
SHARE = {"http": 0.5, "servos": 0.15, "ws": 0.3, "calibrate": 0.05}


def _settings(share: str) -> Any:
    n = max(10, int(TOTAL * SHARE[share]))
    return settings(max_examples=n, deadline=None, suppress_health_check=list(HealthCheck), database=None)


def _jsonable(value: Any) -> Any:
    if isinstance(value, frozenset | set | tuple):
        return [_jsonable(v) for v in sorted(value, key=repr)]
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return value


LIVE: list[tuple[str, str, Any]] = [
    ("POST", "/api/aus", {"aus": {"AU12": 0.4, "AU26": 0.3}, "transition_s": 0.1, "merge": True}),
    ("POST", "/api/aus/clear", {"names": ["AU12"], "transition_s": 0.2}),
    ("POST", "/api/express", {"name": "happiness", "intensity": 0.8, "transition_s": 0.3, "hold_s": 0.5}),
    ("POST", "/api/gaze", {"point_mm": [100.0, 20.0, 600.0]}),
    ("POST", "/api/gaze", {"pad": [0.3, -0.2]}),
    ("POST", "/api/neutral", {"transition_s": 0.3}),
    ("POST", "/api/alive", {"blink": True, "idle": False}),
    ("POST", "/api/stop", {"track": "face", "hold": False, "release_s": 0.2}),
    ("POST", "/api/hold", {"hold": False}),
    ("POST", "/api/scripts/check", {"toml": "[script]\nface = 'human'\n"}),
    ("POST", "/api/scripts/sample", {"document": {"script": {"face": "human"}}, "fps": 5}),
    ("POST", "/api/play", {"document": {"script": {"face": "human"}, "poses": {"a": {"AU12": 0.5}}}}),
    ("PUT", "/api/scripts/f.toml", {"document": {"script": {"face": "human"}}}),
    ("GET", "/api/scripts/f.toml", None),
    ("GET", "/api/state", None),
    ("POST", "/api/calibrate/reply", {"action": "jog", "delta_tick": 5}),
    ("GET", "/api/twin/achievable.png", None),
    ("POST", "/api/calibration/apply", {"file": "nope.json"}),
    ("GET", "/api/record", None),
    ("POST", "/api/record/stop", {}),
]
SERVOS: list[tuple[str, str, Any]] = [
    ("POST", "/api/servos/18/jog", {"delta_tick": 10}),
    ("POST", "/api/servos/18/jog", {"goal_tick": 2100}),
    ("POST", "/api/servos/3/jog", {"delta_tick": -10}),
    ("POST", "/api/servos/18/torque", {"on": True}),
    ("POST", "/api/servos/5/reboot", {}),
    ("GET", "/api/servos", None),
]
WS: list[dict[str, Any]] = [
    {"type": "set_aus", "aus": {"AU12": 0.5, "AU26": 0.2}, "transition_s": 0.05},
    {"type": "clear_aus", "names": None},
    {"type": "express", "name": "surprise", "intensity": 0.5},
    {"type": "gaze", "pad": [0.5, 0.5]},
    {"type": "hold", "hold": False},
    {"type": "subscribe", "twin": False, "telemetry": True},
    {"type": "ping"},
    {"type": "heartbeat"},
]


def mutated_from(bodies: list[Any]) -> st.SearchStrategy[tuple[int, Any]]:
    """(index of the template, a body): the template with one node set to a weird value, dropped, given
    a stray key; or a wholly weird body."""

    @st.composite
    def build(draw: st.DrawFn) -> tuple[int, Any]:
        i = draw(st.integers(0, len(bodies) - 1))
        base = bodies[i]
        how = draw(st.sampled_from(["set", "drop", "extra", "whole", "same"]))
        if how == "same" or base is None:
            return i, base
        if how == "whole":
            return i, _jsonable(draw(values))
        path = draw(st.sampled_from(paths(base)))
        return i, _jsonable(mutate(base, path, draw(values), how))

    return build()


def _quote(text: str) -> str:
    from urllib.parse import quote

    return quote(text, safe="", errors="surrogatepass")


def _check_answer(r: Any) -> None:
    assert r.status_code < 500, (r.status_code, r.text[:500])
    assert 200 <= r.status_code < 300 or 400 <= r.status_code < 500, r.status_code
    if r.status_code >= 400:
        error = r.json()["error"]
        assert error["status"] == r.status_code and error["message"] and isinstance(error["field"], str)


def _send(rig: StudioRig, method: str, path: str, body: Any, raw: bool) -> None:
    if body is None:
        r = rig.client.request(method, path)
    else:
        text = json.dumps(body, allow_nan=True)
        r = rig.client.request(
            method, path, content=text[:-1] if raw else text, headers={"Content-Type": "application/json"}
        )
    _check_answer(r)


def _assert_wire_within_limits(rig: StudioRig, since: int, slack_tick: dict[int, int] | None = None) -> int:
    limits = rig.limits()
    writes = rig.chain.goal_writes()
    for _, sid, tick in writes[since:]:
        if sid == 254:
            continue
        lo, hi = limits[sid]
        extra = (slack_tick or {}).get(sid, 0)
        assert lo - extra <= tick <= hi + extra, f"goal {tick} to servo {sid} outside {lo}..{hi}"
    return len(writes)


def test_fuzzed_requests_and_messages_get_4xx_and_nothing_invalid_reaches_the_wire(tmp_path: Path) -> None:
    rig = _open(tmp_path, render=False)
    try:
        _fuzz(rig)
    finally:
        _close(rig)


def _fuzz(rig: StudioRig) -> None:
    rig.wait_for(lambda: rig.service.last_trace is not None, what="a first frame")
    seen = 0

    @_settings("http")
    @given(mutated_from([b for _, _, b in LIVE]), st.booleans(), st.one_of(st.none(), weird_text))
    def live(pick: tuple[int, Any], raw: bool, odd_path: str | None) -> None:
        method, path, _ = LIVE[pick[0]]
        if odd_path is not None and "{" not in odd_path:
            path = path.rsplit("/", 1)[0] + "/" + _quote(odd_path)
        _send(rig, method, path, pick[1], raw and pick[1] is not None)

    t0 = time.monotonic()
    live()
    print(f"http {time.monotonic() - t0:.1f}s")
    seen = _assert_wire_within_limits(rig, seen)

    assert rig.client.post("/api/servos/manual", json={"on": True}).status_code == 200

    @_settings("servos")
    @given(mutated_from([b for _, _, b in SERVOS]), st.one_of(st.none(), st.integers(-3, 300), weird_text))
    def servos(pick: tuple[int, Any], odd_id: Any) -> None:
        method, path, _ = SERVOS[pick[0]]
        if odd_id is not None and "/servos/" in path and path.count("/") == 4:
            parts = path.split("/")
            parts[3] = _quote(str(odd_id)) or "0"
            path = "/".join(parts)
        _send(rig, method, path, pick[1], False)

    t0 = time.monotonic()
    servos()
    print(f"servos {time.monotonic() - t0:.1f}s")
    assert rig.client.post("/api/servos/manual", json={"on": False}).status_code == 200
    seen = _assert_wire_within_limits(rig, seen)

    from websockets.sync.client import connect

    with connect(rig.ws_url, open_timeout=30, max_queue=None) as ws:
        counter = iter(range(1, 10**9))
        ws.send(json.dumps({"type": "subscribe", "twin": False, "frames": False, "telemetry": False}))

        @_settings("ws")
        @given(mutated_from(WS), st.sampled_from(["json", "text", "bytes"]))
        def messages(pick: tuple[int, Any], form: str) -> None:
            msg_id = next(counter)
            body = pick[1]
            if form == "bytes":
                ws.send(json.dumps(body).encode())
            elif form == "text" or not isinstance(body, dict):
                text = json.dumps(body, allow_nan=True) if form == "json" else str(body)[:200]
                # a text frame is UTF-8 on the wire: a lone surrogate cannot be sent (a browser replaces it too)
                ws.send(text.encode("utf-8", "replace").decode("utf-8"))
            else:
                ws.send(json.dumps({**body, "id": msg_id}, allow_nan=True))
            if form == "json" and isinstance(body, dict):
                while True:  # the answer to this message: a reply or an error with its id, nothing else breaks
                    message = ws.recv(timeout=30)
                    if isinstance(message, bytes):
                        continue
                    data = json.loads(message)
                    if data.get("type") in ("reply", "error") and data.get("id") == msg_id:
                        if data["type"] == "error":
                            assert 400 <= data["error"]["status"] < 500 and data["error"]["message"]
                        break
                return
            ws.send(json.dumps({"type": "ping", "id": 0}))
            while True:  # the socket is alive and in order
                message = ws.recv(timeout=30)
                if isinstance(message, str) and (d := json.loads(message)).get("id") == 0 and d["type"] == "reply":
                    break

        t0 = time.monotonic()
        messages()
        print(f"ws {time.monotonic() - t0:.1f}s")
        ws.send(json.dumps({"type": "hold", "hold": True}))  # leaving without easing keeps the last check simple
    seen = _assert_wire_within_limits(rig, seen)

    # calibration replies, with a session on the jaw (the procedure's own safe window applies to it)
    jaw = next(s for s in rig.client.get("/api/head").json()["servos"] if s["role"] == "jaw")
    r = rig.client.post("/api/calibrate/start", json={"roles": ["jaw"], "points": 1, "out": "fuzz.json"})
    assert r.status_code == 200, r.text
    template = [
        {"action": "jog", "delta_tick": 10},
        {"action": "goto", "tick": 2100},
        {"action": "capture", "target": 1.0},
    ]

    @_settings("calibrate")
    @given(mutated_from(template))
    def replies(pick: tuple[int, Any]) -> None:
        _send(rig, "POST", "/api/calibrate/reply", pick[1], False)

    replies()
    rig.client.post("/api/calibrate/reply", json={"action": "abort"})
    rig.wait_for(lambda: rig.client.get("/api/calibrate").json()["done"], what="the session's end")
    margin = 40  # ProcedureOptions.window_margin_tick: the window before the limits are captured
    _assert_wire_within_limits(rig, seen, {jaw["id"]: margin})
    assert math.isfinite(rig.service.now_s()) and rig.service.error is None
