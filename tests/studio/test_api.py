"""The studio's API over real sockets (uvicorn on an ephemeral loopback port, httpx and a WebSocket
client), on the emulated human head: what it does is read from the emulator."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import httpx
import pytest
from servoface.controller.studio import StudioError, StudioServer
from websockets.exceptions import InvalidStatus

from tests.studio.conftest import StudioRig


def _wrong(token: str) -> str:
    """The token with its last character changed (to "x", or "y" if it was an "x": a token drawn ending
    in "x" once made the "wrong" token the right one)."""
    return token[:-1] + ("y" if token.endswith("x") else "x")


def _servo(rig: StudioRig, role: str) -> dict[str, Any]:
    return next(s for s in rig.client.get("/api/head").json()["servos"] if s["role"] == role)


# -- security -----------------------------------------------------------------------------------------
def test_requests_without_the_token_are_refused_and_move_nothing(studio: StudioRig) -> None:
    jaw = _servo(studio, "jaw")["id"]
    before = studio.goal_tick(jaw)
    bare = httpx.Client(base_url=studio.base_url, timeout=30)
    for headers in ({}, {"Authorization": "Bearer wrong"}, {"X-Servoface-Token": _wrong(studio.token)}):
        for method, path, body in (("GET", "/api/head", None), ("POST", "/api/aus", {"aus": {"AU26": 1.0}}),
                                   ("GET", "/", None), ("POST", "/api/estop", {})):  # fmt: skip
            r = bare.request(method, path, json=body, headers=headers)
            assert r.status_code == 401, (path, headers, r.text)
            assert r.json()["error"]["code"] == "unauthorized"
    with pytest.raises(InvalidStatus):
        from websockets.sync.client import connect

        connect(f"ws://127.0.0.1:{studio.server.port}/api/ws", open_timeout=20)
    assert not studio.service.estop_latched
    assert studio.goal_tick(jaw) == before
    # the token in the query (the printed URL) sets the cookie, which then works on its own
    page = bare.get(f"/?token={studio.token}")
    assert page.status_code == 200 and "servoface_token" in page.headers.get("set-cookie", "")
    jar = httpx.Client(base_url=studio.base_url, timeout=30, cookies={"servoface_token": studio.token})
    assert jar.get("/api/head").status_code == 200


def test_foreign_origins_are_refused(studio_shared: StudioRig) -> None:
    r = studio_shared.client.post("/api/aus", json={"aus": {"AU26": 1.0}}, headers={"Origin": "http://evil.example"})
    assert r.status_code == 403 and r.json()["error"]["code"] == "forbidden_origin"
    own = f"http://localhost:{studio_shared.server.port}"
    assert studio_shared.client.get("/api/state", headers={"Origin": own}).status_code == 200
    from websockets.sync.client import connect

    with pytest.raises(InvalidStatus):
        connect(studio_shared.ws_url, origin="http://evil.example", open_timeout=20)  # type: ignore[arg-type]


def test_body_size_and_rate_limits(make_studio: Any) -> None:
    rig = make_studio(rate=5.0)
    big = {"aus": {"AU26": 0.1}, "pad": "x" * (2 << 20)}
    r = rig.client.post("/api/aus", json=big)
    assert r.status_code in (413, 429)
    codes = [rig.client.get("/api/state").status_code for _ in range(20)]
    assert 429 in codes and set(codes) <= {200, 429}
    refused = next(c for c in codes if c == 429)
    assert refused == 429


def test_body_over_one_mib_is_413(studio_shared: StudioRig) -> None:
    r = studio_shared.client.post(
        "/api/aus", content=b"{" + b" " * (2 << 20) + b"}", headers={"Content-Type": "application/json"}
    )
    assert r.status_code == 413 and r.json()["error"]["code"] == "too_large"


def test_non_loopback_bind_needs_allow_remote(studio_shared: StudioRig) -> None:
    with pytest.raises(StudioError, match="allow-remote"):
        StudioServer(studio_shared.service, host="0.0.0.0", port=0)


# -- errors -------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("path", "body", "status", "field"),
    [
        ("/api/aus", {"aus": {"AU99": 0.5}}, 422, "aus.AU99"),
        ("/api/aus", {"aus": {"AU12": "high"}}, 422, "aus.AU12"),
        ("/api/aus", {"aus": {"AU12": 0.5}, "transition_s": -1}, 422, "transition_s"),
        ("/api/aus", {"aus": {"AU12": 0.5}, "speed": 1}, 422, "speed"),
        ("/api/aus", [1, 2], 400, ""),
        ("/api/express", {"name": "no_such", "intensity": 0.5}, 422, "name"),
        ("/api/express", {"name": "happiness", "intensity": 2}, 422, "intensity"),
        ("/api/gaze", {"pad": [0.5, 3]}, 422, "pad.1"),
        ("/api/servos/99/torque", {"on": False}, 404, "id"),
        ("/api/servos/1/jog", {"delta_tick": 10}, 409, ""),
        ("/api/calibrate/start", {"roles": ["elbow"]}, 422, "roles"),
        ("/api/calibrate/start", {"out": "../../etc/passwd"}, 422, "out"),
        ("/api/scripts/check", {"toml": "[script]\nface = 'cat'\n"}, 422, "toml.script.face"),
    ],
)
def test_bad_values_are_clear_4xx_naming_the_field(
    studio_shared: StudioRig, path: str, body: Any, status: int, field: str
) -> None:
    r = studio_shared.client.post(path, json=body)
    assert r.status_code == status, r.text
    error = r.json()["error"]
    assert error["status"] == status and error["message"]
    assert error["field"] == field


# -- live ---------------------------------------------------------------------------------------------
def test_a_slider_moves_the_emulated_servo(studio: StudioRig) -> None:
    jaw = _servo(studio, "jaw")
    before = studio.goal_tick(jaw["id"])
    r = studio.client.post("/api/aus", json={"aus": {"AU26": 0.8}, "transition_s": 0.1})
    assert r.status_code == 202 and r.json()["command"]["kind"] == "set_aus"
    studio.wait_for(lambda: abs(studio.goal_tick(jaw["id"]) - before) > 50, what="the jaw goal to move")
    lo, hi = jaw["min_tick"], jaw["max_tick"]
    assert lo <= studio.goal_tick(jaw["id"]) <= hi


def test_websocket_slider_replies_and_moves_the_servo(studio: StudioRig) -> None:
    jaw = _servo(studio, "jaw")["id"]
    before = studio.goal_tick(jaw)
    with studio.connect() as ws:
        ws.send(json.dumps({"type": "set_aus", "id": 7, "aus": {"AU26": 0.7}}))
        ws.send(json.dumps({"type": "set_aus", "id": 8, "aus": {"AU26": 7}}))
        replies: dict[int, Any] = {}
        kinds: set[str] = set()
        while len(replies) < 2 or not {"frame", "telemetry", "state"} <= kinds:
            message = json.loads(ws.recv(timeout=20))
            kinds.add(message["type"])
            if message["type"] in ("reply", "error") and message["id"] in (7, 8):
                replies[message["id"]] = message
        assert replies[7]["type"] == "reply" and replies[7]["result"]["command"]["kind"] == "set_aus"
        assert replies[8]["type"] == "error" and replies[8]["error"]["field"] == "aus.AU26"
        studio.wait_for(lambda: abs(studio.goal_tick(jaw) - before) > 50, what="the jaw goal to move")


def test_estop_turns_every_servo_off_and_latches(studio: StudioRig) -> None:
    studio.client.post("/api/aus", json={"aus": {"AU26": 0.5}})
    with studio.connect() as ws:
        ws.send(json.dumps({"type": "estop", "reason": "test"}))
        studio.wait_for(lambda: all(studio.torque(s) == 0 for s in studio.chain.ids), what="torque off everywhere")
    r = studio.client.post("/api/aus", json={"aus": {"AU26": 0.5}})
    assert r.status_code == 409 and "e-stop" in r.json()["error"]["message"]
    assert studio.client.post("/api/torque", json={"on": True}).status_code == 409
    assert studio.client.post("/api/estop/clear", json={}).status_code == 200
    assert all(studio.torque(s) == 0 for s in studio.chain.ids)  # clearing does not power anything
    assert studio.client.post("/api/torque", json={"on": True}).status_code == 200
    studio.wait_for(lambda: all(studio.torque(s) == 1 for s in studio.chain.ids), what="torque back on")


def _neutral_goals(rig: StudioRig) -> dict[int, int]:
    rig.wait_for(lambda: rig.service.last_trace is not None, what="a first frame")
    trace = rig.service.last_trace
    assert trace is not None
    return dict(trace.goals_sent)


def test_a_dropped_browser_eases_the_head_to_neutral_within_a_second(studio: StudioRig) -> None:
    neutral = _neutral_goals(studio)
    traces = studio.service.subscribe("trace", maxlen=4096)
    with studio.connect() as ws:
        ws.send(json.dumps({"type": "set_aus", "aus": {"AU26": 0.8, "AU12": 0.6}, "transition_s": 0.1}))
        held = lambda: studio.service.status().tracks["studio"].state == "holding"  # noqa: E731
        studio.wait_for(lambda: studio.goals() != neutral and held(), what="the pose")
        ws.close()  # the tab closes
    studio.wait_for(lambda: studio.goals() == neutral, what="the emulated servos' goals back at neutral")
    drop_s = studio.client.get("/api/state").json()["last_drop_s"]
    assert drop_s is not None
    landed = [t for t in traces.drain() if t.t_s >= drop_s and t.goals_sent == neutral]
    assert landed, "no frame sent the neutral goals"
    assert landed[0].t_s - drop_s <= 1.0  # service-clock frame times: the ease is 0.6 s by construction
    traces.close()


def test_hold_keeps_the_pose_when_the_browser_drops(studio: StudioRig) -> None:
    neutral = _neutral_goals(studio)
    with studio.connect() as ws:
        ws.send(json.dumps({"type": "hold", "id": 1, "hold": True}))
        ws.send(json.dumps({"type": "set_aus", "aus": {"AU26": 0.8}, "transition_s": 0.1}))
        studio.wait_for(lambda: studio.service.status().tracks["studio"].state == "holding", what="the pose held")
        # "holding" is the track's state; the wire goals may still be catching up (speed caps) for a few
        # frames on a loaded machine: take the pose once it has stopped changing
        seen: list[tuple[int, dict[int, int]]] = []

        def settled() -> bool:
            index, goals = studio.service.last_trace.index, studio.goals()  # type: ignore[union-attr]
            seen.append((index, goals))
            earlier = [g for i, g in seen if i <= index - 10]
            return bool(earlier) and earlier[-1] == goals

        studio.wait_for(settled, what="the wire goals settled (unchanged over 10 frames)")
        posed = seen[-1][1]
        assert posed != neutral
        ws.close()
    studio.wait_for(lambda: studio.client.get("/api/state").json()["clients"] == 0, what="the drop noticed")
    frame = studio.service.last_trace.index  # type: ignore[union-attr]
    studio.wait_for(lambda: studio.service.last_trace.index > frame + 25, what="half a second of frames")  # type: ignore[union-attr]
    assert studio.goals() == posed


def test_express_and_gaze_and_neutral(studio: StudioRig) -> None:
    neutral = _neutral_goals(studio)
    assert studio.client.post("/api/express", json={"name": "happiness", "intensity": 0.7}).status_code == 202
    assert studio.client.post("/api/gaze", json={"pad": [0.8, 0.0]}).status_code == 202
    studio.wait_for(lambda: studio.goals() != neutral, what="the expression")
    assert studio.client.post("/api/neutral", json={"transition_s": 0.3}).status_code == 202
    studio.wait_for(lambda: studio.goals() == neutral, what="neutral")


# -- servos -------------------------------------------------------------------------------------------
def test_manual_jog_within_limits_torque_and_reboot(studio: StudioRig) -> None:
    jaw = _servo(studio, "jaw")
    sid = jaw["id"]
    assert studio.client.post("/api/servos/manual", json={"on": True}).json() == {"manual": True}
    base = studio.goal_tick(sid)
    r = studio.client.post(f"/api/servos/{sid}/jog", json={"delta_tick": 40})
    assert r.status_code == 200, r.text
    studio.wait_for(lambda: studio.goal_tick(sid) == base + 40, what="the jog on the wire")
    for body, field in (({"goal_tick": jaw["max_tick"] + 1}, "goal_tick"), ({"delta_tick": -4000}, "delta_tick"),
                        ({"delta_tick": 301}, "delta_tick")):  # fmt: skip
        r = studio.client.post(f"/api/servos/{sid}/jog", json=body)
        assert r.status_code == 422 and r.json()["error"]["field"] == field, r.text
    assert studio.goal_tick(sid) == base + 40
    # telemetry is live in manual mode too
    entry = next(s for s in studio.client.get("/api/servos").json()["servos"] if s["id"] == sid)
    assert set(entry) >= {"position_tick", "goal_tick", "load_pct", "temperature_c", "voltage_v", "faults"}
    assert studio.client.post(f"/api/servos/{sid}/torque", json={"on": False}).status_code == 200
    assert studio.torque(sid) == 0
    assert studio.client.post(f"/api/servos/{sid}/torque", json={"on": True}).status_code == 200
    assert studio.torque(sid) == 1
    assert studio.client.post(f"/api/servos/{sid}/reboot", json={}).status_code == 200
    assert studio.client.post("/api/servos/manual", json={"on": False}).json() == {"manual": False}
    assert studio.client.post("/api/aus", json={"aus": {"AU26": 0.2}}).status_code == 202


def test_estop_in_manual_mode_turns_torque_off_at_once(studio: StudioRig) -> None:
    studio.client.post("/api/servos/manual", json={"on": True})
    assert studio.client.post("/api/estop", json={"reason": "manual"}).status_code == 202
    studio.wait_for(lambda: all(studio.torque(s) == 0 for s in studio.chain.ids), what="torque off everywhere")
    assert studio.client.get("/api/state").json()["manual"] is False


# -- author -------------------------------------------------------------------------------------------
SMILE = {
    "script": {"face": "human", "title": "two keys"},
    "expressions": {
        "smile": {
            "keyframes": [
                {"t_s": 0.0, "pose": {"AU12": 0.0}},
                {"t_s": 0.6, "pose": {"AU12": 0.8, "AU26": 0.3}, "easing": "ease_in_out"},
            ]
        }
    },
    "play": [{"at_s": 0.0, "expression": "smile"}],
}


def test_a_script_name_with_a_path_is_refused_by_name_not_with_a_404(studio: StudioRig, tmp_path: Path) -> None:
    """What the Author page sends for '../evil name.toml' (encodeURIComponent): a 422 naming the field."""
    for raw in ("..%2Fevil%20name.toml", "a%2Fb.toml", "..%2F..%2Fetc%2Fx.toml"):
        r = studio.client.put(f"/api/scripts/{raw}", json={"document": SMILE})
        assert r.status_code == 422, (raw, r.status_code, r.text)
        assert r.json()["error"]["field"] == "name" and "bare file name" in r.json()["error"]["message"]
        assert studio.client.get(f"/api/scripts/{raw}").status_code == 422
    assert not list(tmp_path.parent.glob("evil*")) and not list(tmp_path.glob("**/*.toml"))


def test_script_round_trip_without_loss(studio: StudioRig, tmp_path: Path) -> None:
    r = studio.client.put("/api/scripts/smile.toml", json={"document": SMILE})
    assert r.status_code == 200, r.text
    assert Path(r.json()["path"]) == (tmp_path / "smile.toml").resolve()
    loaded = studio.client.get("/api/scripts/smile.toml").json()
    assert loaded["document"] == SMILE
    assert loaded["summary"]["end_s"] == pytest.approx(0.6)
    assert "smile.toml" in studio.client.get("/api/scripts").json()["scripts"]
    # saved again from what was loaded: byte for byte the same file
    first = (tmp_path / "smile.toml").read_bytes()
    studio.client.put("/api/scripts/smile.toml", json={"document": loaded["document"]})
    assert (tmp_path / "smile.toml").read_bytes() == first
    # the script parser is the one `servoface play` uses
    from servoface.controller.script import load_script

    assert load_script(tmp_path / "smile.toml").end_s == pytest.approx(0.6)
    frames = studio.client.post("/api/scripts/sample", json={"document": SMILE, "fps": 10}).json()["frames"]
    assert frames[-1]["aus"]["AU12"] == pytest.approx(0.8)
    # text keeps comments
    text = "# mine\n" + (tmp_path / "smile.toml").read_text()
    assert studio.client.put("/api/scripts/commented.toml", json={"toml": text}).status_code == 200
    assert (tmp_path / "commented.toml").read_text() == text


def test_script_errors_name_the_key_path_and_write_nothing(studio: StudioRig, tmp_path: Path) -> None:
    bad = json.loads(json.dumps(SMILE))
    bad["expressions"]["smile"]["keyframes"][1]["pose"]["AU12"] = 3.0
    r = studio.client.put("/api/scripts/bad.toml", json={"document": bad})
    assert r.status_code == 422
    assert r.json()["error"]["field"].startswith("document.expressions.smile.keyframes")
    assert not (tmp_path / "bad.toml").exists()
    for name in ("../x.toml", "x.json", ".hidden.toml"):
        assert studio.client.put(f"/api/scripts/{name}", json={"document": SMILE}).status_code in (404, 422)


def test_a_script_file_over_the_limit_is_refused_unread(studio: StudioRig, tmp_path: Path) -> None:
    """Before: a script of the scripts folder was read whole, however large, and sent back in the answer."""
    with (tmp_path / "huge.toml").open("wb") as fh:
        fh.truncate(16 * 2**20 + 1)  # declared, no blocks written
    r = studio.client.get("/api/scripts/huge.toml")
    assert r.status_code == 422, r.text
    error = r.json()["error"]
    assert error["field"] == "name", error
    assert error["message"] == f"name: cannot read huge.toml: {16 * 2**20 + 1} bytes; a script file is at most 16 MiB"


def _answer(ws: Any, message: dict[str, Any]) -> dict[str, Any]:
    """The reply or error to ``message`` (messages are answered in order; pushes in between are skipped)."""
    ws.send(json.dumps(message))
    while True:
        raw = ws.recv(timeout=20)
        if isinstance(raw, str) and (data := json.loads(raw))["type"] in ("reply", "error"):
            return dict(data)


def test_websocket_id_is_a_short_string_or_a_safe_integer_never_echoed_otherwise(studio_shared: StudioRig) -> None:
    """Before: a 400-digit integer id was echoed back as given (no JavaScript number holds it), a string id
    (what browser clients often use) was refused."""
    with studio_shared.connect() as ws:
        ws.send(json.dumps({"type": "subscribe", "twin": False, "frames": False, "telemetry": False}))
        for good in ("a1b2-c3", "x" * 128, 2**53, -(2**53), 0):
            answer = _answer(ws, {"type": "ping", "id": good})
            assert answer["type"] == "reply" and answer["id"] == good, answer
        for bad, got in [
            (10**400, "an integer of 401 digits"),
            (2**53 + 1, "an integer of 16 digits"),
            ("x" * 129, "a string of 129 characters"),
            (1.5, "float 1.5"),
            ([7], "list [7]"),
        ]:
            answer = _answer(ws, {"type": "ping", "id": bad})
            assert answer["type"] == "error" and answer["id"] is None, answer
            assert answer["error"]["field"] == "id" and answer["error"]["status"] == 422, answer
            assert answer["error"]["message"] == (
                f"id: expected a string of at most 128 characters or an integer within ±2^53, got {got}"
            ), answer
        assert _answer(ws, {"type": "ping", "id": 5})["type"] == "reply"  # the socket stays open


def test_shipped_scripts_load_and_play_by_their_bare_name(studio: StudioRig, tmp_path: Path) -> None:
    from servoface.controller.shipped import shipped_scripts

    listed = studio.client.get("/api/scripts").json()["shipped"]
    assert "human_performance" in listed
    text = shipped_scripts()["human_performance"].read_text(encoding="utf-8")
    for spec in ("human_performance", "human_performance.toml", "script:human_performance"):
        r = studio.client.get(f"/api/scripts/{spec}")
        assert r.status_code == 200, (spec, r.text)
        assert r.json()["toml"] == text
        assert r.json()["summary"]["face"] == "human"
    # the folder's own copy comes first (except with script:), and unknown names are a clear 404
    studio.client.put("/api/scripts/human_performance.toml", json={"document": SMILE})
    assert studio.client.get("/api/scripts/human_performance").json()["document"] == SMILE
    assert studio.client.get("/api/scripts/script:human_performance").json()["toml"] == text
    r = studio.client.get("/api/scripts/no_such_script")
    assert r.status_code == 404 and r.json()["error"]["field"] == "name"
    assert studio.client.get("/api/scripts/..%2Fhuman_performance").status_code in (404, 422)
    (tmp_path / "human_performance.toml").unlink()
    neutral = _neutral_goals(studio)
    r = studio.client.post("/api/play", json={"name": "human_performance"})
    assert r.status_code == 202, r.text
    studio.wait_for(lambda: studio.goals() != neutral, what="the shipped script on the wire")


def test_play_a_saved_script_on_the_head(studio: StudioRig) -> None:
    neutral = _neutral_goals(studio)
    studio.client.put("/api/scripts/smile.toml", json={"document": SMILE})
    r = studio.client.post("/api/play", json={"name": "smile.toml"})
    assert r.status_code == 202, r.text
    studio.wait_for(lambda: studio.goals() != neutral, what="the script on the wire")


# -- calibrate ----------------------------------------------------------------------------------------
def _wait_prompt(rig: StudioRig, step: str, present: int | None = None) -> dict[str, Any]:
    def ready() -> bool:
        p = rig.client.get("/api/calibrate").json()["prompt"]
        return p is not None and p["step"] == step and (present is None or p["present_tick"] == present)

    rig.wait_for(ready, what=f"the {step} prompt at {present}")
    return rig.client.get("/api/calibrate").json()["prompt"]  # type: ignore[no-any-return]


def test_calibrate_through_http_writes_the_file_the_cli_writes(
    studio: StudioRig, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same captures as tests/calibration/test_cli_calibrate.py's interactive run: neutral at 2048, the
    shipped calibration's 25 deg ("g"), then a free point 142 ticks back typed in degrees."""
    up = round(25 * 4096 / 360)
    free_deg = 142 * 360 / 4096
    r = studio.client.post(
        "/api/calibrate/start", json={"roles": ["jaw"], "points": 0, "free_points": True, "out": "jaw.json"}
    )
    assert r.status_code == 200, r.text
    assert studio.client.post("/api/aus", json={"aus": {"AU26": 0.5}}).status_code == 409  # the bus is lent
    _wait_prompt(studio, "neutral", 2048)
    studio.client.post("/api/calibrate/reply", json={"action": "capture"})
    p = _wait_prompt(studio, "upper")
    assert p["suggested_tick"] == 2048 + up
    studio.client.post("/api/calibrate/reply", json={"action": "goto_suggested"})
    _wait_prompt(studio, "upper", 2048 + up)
    studio.client.post("/api/calibrate/reply", json={"action": "capture"})
    _wait_prompt(studio, "extra")
    r = studio.client.post("/api/calibrate/reply", json={"action": "goto", "tick": 5000})
    assert r.status_code == 422 and r.json()["error"]["field"] == "tick"
    studio.client.post("/api/calibrate/reply", json={"action": "jog", "delta_tick": -142})
    _wait_prompt(studio, "extra", 2048 + up - 142)
    studio.client.post("/api/calibrate/reply", json={"action": "capture", "target": free_deg})
    _wait_prompt(studio, "extra")
    state = studio.client.post("/api/calibrate/reply", json={"action": "finish"}).json()
    studio.wait_for(lambda: studio.client.get("/api/calibrate").json()["done"], what="the session's end")
    state = studio.client.get("/api/calibrate").json()
    assert state["error"] == "" and state["result"]["saved_to"] == str((tmp_path / "jaw.json").resolve())
    assert [c["tick"] for c in state["captured"]] == [2048, 2048 + up, 2048 + up - 142]
    assert studio.client.get("/api/calibrate/plot/jaw.png").content[:8] == b"\x89PNG\r\n\x1a\n"
    # the loop has the bus back, driving with the new calibration (no restart)
    assert state["result"]["applied"] is True
    from servoface.calibration import load_calibration

    saved = load_calibration(tmp_path / "jaw.json")["jaw"]
    running = studio.service.pipeline.calibration["jaw"]
    assert (running.min_tick, running.max_tick) == (saved.min_tick, saved.max_tick)
    assert running.neutral_tick == saved.neutral_tick
    assert running.to_tick(free_deg) == saved.to_tick(free_deg)
    assert studio.client.post("/api/aus", json={"aus": {"AU26": 0.2}}).status_code == 202

    # the CLI, same head, same captures
    import time

    from servoface.controller.cli import main

    keys = ["", "g", "", "-142", f"={free_deg}", "d"]

    def fake_input(prompt: str = "") -> str:
        time.sleep(0.15)
        if not keys:
            raise EOFError
        return keys.pop(0)

    monkeypatch.setattr("builtins.input", fake_input)
    cli_out = tmp_path / "cli-jaw.json"
    argv = ["calibrate", "--head", "human", "--emulate", "--roles", "jaw", "--points", "0", "--free-points"]
    assert main([*argv, "--out", str(cli_out)]) == 0

    def without_time(path: Path) -> dict[str, Any]:
        data = json.loads(path.read_text())
        data["metadata"].pop("created_utc")
        return data  # type: ignore[no-any-return]

    assert without_time(tmp_path / "jaw.json") == without_time(cli_out)


def test_calibration_abort_saves_nothing_and_estop_ends_it(studio: StudioRig, tmp_path: Path) -> None:
    studio.client.post("/api/calibrate/start", json={"roles": ["jaw"], "points": 0, "out": "never.json"})
    _wait_prompt(studio, "neutral")
    studio.client.post("/api/estop", json={})
    studio.wait_for(lambda: studio.client.get("/api/calibrate").json()["done"], what="the session's end")
    assert "aborted" in studio.client.get("/api/calibrate").json()["error"]
    assert not (tmp_path / "never.json").exists()
    studio.wait_for(lambda: all(studio.torque(s) == 0 for s in studio.chain.ids), what="torque off everywhere")


# -- the twin -----------------------------------------------------------------------------------------
def test_twin_renders_at_640x480_over_http_and_the_websocket(studio_render: StudioRig) -> None:
    import io

    from PIL import Image

    rig = studio_render
    assert rig.server.studio.renderer is not None and rig.server.studio.renderer.wait_ready(120)
    rig.wait_for(lambda: rig.service.last_trace is not None, what="a first frame")
    for which in ("achievable", "target"):
        r = rig.client.get(f"/api/twin/{which}.png")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png"
        assert Image.open(io.BytesIO(r.content)).size == (640, 480)
    with rig.connect() as ws:
        ws.send(json.dumps({"type": "subscribe", "target": True}))
        ws.send(json.dumps({"type": "set_aus", "aus": {"AU12": 0.8}}))
        seen = set()
        while seen != {0x41, 0x54}:
            message = ws.recv(timeout=60)
            if isinstance(message, bytes):
                seen.add(message[0])
                assert Image.open(io.BytesIO(message[5:])).size == (640, 480)
    preview = rig.client.post("/api/scripts/preview", json={"document": SMILE, "t_s": 0.6})
    assert preview.status_code == 200 and Image.open(io.BytesIO(preview.content)).size == (640, 480)


def test_cli_refuses_a_non_loopback_host_without_allow_remote(capsys: pytest.CaptureFixture[str]) -> None:
    from servoface.controller.cli import main

    assert main(["studio", "--head", "human", "--emulate", "--host", "0.0.0.0"]) == 2
    assert "--allow-remote" in capsys.readouterr().err
