"""Heads as Zenoh nodes, in separate processes on loopback, checked from each emulator's side of the wire
(the goals every emulated servo received, with their monotonic times: one clock for every process here).

The module starts three `servoface node` processes (user/password authentication on) and drives them from
this process and from helper processes. The tests assert what must happen, with bounds loose enough for a
loaded machine; the figures against their goals (cue skew <= 20 ms, stream p99 <= 30 ms and < 1 % late,
neutral within 1 s of a cut link, gone from the list within 1 s of a kill) are `servoface bench network`."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from servoface.controller.network.client import HeadsClient
from servoface.controller.network.keys import head_keys
from servoface.controller.network.testbed import ENV, NodeProc, onset_after, start_nodes
from servoface.controller.network.zconfig import Credentials, open_session
from servoface.sim.heads import load_head

pytestmark = pytest.mark.slow

HEAD = load_head("human")
JAW = HEAD.servo_ids["jaw"]
BROW = HEAD.servo_ids["brow_inner_l"]


@pytest.fixture(scope="module")
def net(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    tmp = tmp_path_factory.mktemp("zenoh")
    users = tmp / "users.txt"
    users.write_text("operator:op-secret\nnode:node-secret\n")
    nodes = start_nodes(tmp, ["h1", "h2", "h3"], users_file=users)
    session = open_session(connect=[n.endpoint for n in nodes], creds=Credentials("operator", "op-secret"))
    client = HeadsClient(session)
    deadline = time.monotonic() + 30
    while len(client.heads("lobby/*")) < 3 and time.monotonic() < deadline:
        time.sleep(0.3)
    try:
        yield tmp, nodes, client, users
    finally:
        session.close()
        for n in nodes:
            n.stop()


def _helper(tmp: Path, code: str) -> subprocess.Popen[str]:
    script = tmp / f"helper_{time.monotonic_ns()}.py"
    script.write_text(code)
    return subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV
    )


def _until_ready(head: str) -> str:
    """Helper-process code that waits until the head answers a status query (the routes from this new session
    to the node exist) before the helper publishes: a put sent before that may be dropped by Zenoh."""
    return (
        f"_k = head_keys('lobby', '{head}')\n"
        "_deadline = time.monotonic() + 30\n"
        "while not c.status(_k, timeout_s=1.0) and time.monotonic() < _deadline:\n"
        "    time.sleep(0.1)\n"
        "time.sleep(0.3)\n"
    )


def _wait_for(cond, timeout_s: float = 15.0, every_s: float = 0.1):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while True:
        value = cond()
        if value or time.monotonic() > deadline:
            return value
        time.sleep(every_s)


def test_all_three_heads_are_present_with_their_status(net) -> None:  # type: ignore[no-untyped-def]
    _, nodes, client, _ = net
    heads = client.heads("lobby/*", timeout_s=5.0)  # (each status asked with it too: a loaded machine)
    assert sorted(h.name for h in heads) == ["h1", "h2", "h3"]
    for h in heads:
        assert h.status["face_type"] == "human" and "AU12" in h.status["aus"] and h.status["running"]
        assert "happiness" in h.status["expressions"] and len(h.status["servos"]) == len(HEAD.actuators)


def test_a_cue_starts_on_all_three_within_20_ms(net) -> None:  # type: ignore[no-untyped-def]
    _, nodes, client, _ = net
    time.sleep(0.5)
    result = client.cue(
        "lobby/*", {"verb": "express", "name": "surprise", "transition_s": 0.4, "hold_s": 0.5}, in_s=1.0
    )
    cue_t = result["at_monotonic_s"]

    def onsets_now() -> dict[str, float | None]:
        return {n.name: onset_after(n.goals(BROW, cue_t - 1.0), cue_t - 0.3) for n in nodes}

    _wait_for(lambda: time.monotonic() > cue_t + 1.0 and all(v is not None for v in onsets_now().values()), 15.0)
    onsets = onsets_now()
    assert all(v is not None for v in onsets.values()), onsets
    times = np.array(list(onsets.values()))
    print(f"cue onsets after the cue time (ms): { ({k: round((v - cue_t) * 1e3, 1) for k, v in onsets.items()}) }")
    assert (times - cue_t).min() > -0.005, "a head moved before the cue time"
    assert (times - cue_t).max() < 2.0, "a head started the cue late (or never)"
    for off in result["heads"].values():
        assert off["error_s"] < 0.05
    client.send(head_keys("lobby", "h1"), "neutral")
    client.send(head_keys("lobby", "h2"), "neutral")
    client.send(head_keys("lobby", "h3"), "neutral")


def test_a_50_hz_stream_from_another_process_reaches_the_wire_within_30_ms(net) -> None:  # type: ignore[no-untyped-def]
    tmp, nodes, client, _ = net
    node = nodes[0]
    steps_log = tmp / "steps.json"
    before = client.status(head_keys("lobby", "h1"), timeout_s=5.0)
    code = f"""
import json, time
from servoface.controller.network.client import HeadsClient
from servoface.controller.network.keys import head_keys
from servoface.controller.network.zconfig import Credentials, open_session
s = open_session(connect=["{node.endpoint}"], creds=Credentials("operator", "op-secret"))
c = HeadsClient(s)
k = head_keys("lobby", "h1")
{_until_ready("h1")}steps, value, t0 = [], 0.0, time.monotonic()
for i in range(250):  # 5 s at 50 Hz, the jaw stepping between 0 and 0.5 every 0.4 s
    due = t0 + i / 50
    time.sleep(max(0.0, due - time.monotonic()))
    new = 0.5 if (i // 20) % 2 else 0.0
    t = time.monotonic()
    c.send_aus(k, {{"AU26": new}}, t_s=t)
    if new != value:
        steps.append(t)
    value = new
json.dump(steps, open("{steps_log}", "w"))
time.sleep(0.3)
s.close()
"""
    helper = _helper(tmp, code)
    out, err = helper.communicate(timeout=120)
    assert helper.returncode == 0, err
    steps = json.loads(steps_log.read_text())
    time.sleep(0.3)
    goals = node.goals(JAW, steps[0] - 1.0)
    lat = []
    for t in steps:
        onset = onset_after(goals, t - 0.001, min_change=1)
        assert onset is not None, f"no jaw goal change after the step at {t:.3f}"
        lat.append(onset - t)
    lat_ms = np.array(lat) * 1e3
    after = client.status(head_keys("lobby", "h1"), timeout_s=5.0)
    late = (after["late"] - before["late"]) / max(after["frames"] - before["frames"], 1)
    print(
        f"stream publish -> goal on the wire: median {np.median(lat_ms):.1f} ms, "
        f"p99 {np.percentile(lat_ms, 99):.1f} ms "
        f"over {len(lat_ms)} steps; late frames {late:.1%}"
    )
    assert len(lat_ms) >= 10 and np.median(lat_ms) <= 200.0


def test_a_peer_without_the_credentials_cannot_move_a_head(net) -> None:  # type: ignore[no-untyped-def]
    tmp, nodes, client, _ = net
    node = nodes[1]
    code = f"""
import time
from servoface.controller.network.client import HeadsClient
from servoface.controller.network.keys import head_keys
from servoface.controller.network.zconfig import Credentials, open_session
for creds in (Credentials("operator", "wrong"), Credentials("mallory", "x"), Credentials()):
    s = open_session(connect=["{node.endpoint}"], creds=creds)
    c = HeadsClient(s)
    time.sleep(0.5)
    print("sees", len(c.heads("lobby/*", timeout_s=0.5)))
    for _ in range(20):
        c.send(head_keys("lobby", "h2"), "express", name="happiness", transition_s=0.2)
        c.send_aus(head_keys("lobby", "h2"), {{"AU26": 0.8}})
        time.sleep(0.02)
    s.close()
"""
    t0 = time.monotonic()
    helper = _helper(tmp, code)
    out, err = helper.communicate(timeout=120)
    assert helper.returncode == 0, err
    assert out.split() == ["sees", "0"] * 3, out
    time.sleep(0.5)
    for sid in (JAW, BROW, HEAD.servo_ids["lip_corner_l"]):
        goals = node.goals(sid, t0 - 0.5)
        assert goals and max(g for _, g in goals) - min(g for _, g in goals) <= 2, f"servo {sid} moved"


def test_frames_with_an_unknown_schema_version_move_nothing(net) -> None:  # type: ignore[no-untyped-def]
    _, nodes, client, _ = net
    node = nodes[2]
    keys = head_keys("lobby", "h3")
    before = client.status(keys, timeout_s=5.0)["counters"]["refused"]
    t0 = time.monotonic()
    for i in range(20):
        client.session.put(
            keys.aus("stream"),
            json.dumps({"schema": 2, "seq": 10_000 + i, "t": time.monotonic(), "aus": {"AU26": 0.9}}).encode(),
        )
        client.session.put(keys.cmd("express"), json.dumps({"schema": 99, "seq": 1, "name": "happiness"}).encode())
        client.session.put(keys.cmd("express"), json.dumps({"seq": 2, "name": "happiness"}).encode())
        time.sleep(0.02)
    time.sleep(0.8)
    for sid in (JAW, HEAD.servo_ids["lip_corner_l"]):
        goals = node.goals(sid, t0 - 0.2)
        assert max(g for _, g in goals) - min(g for _, g in goals) <= 2, f"servo {sid} moved"
    refused = client.status(keys, timeout_s=5.0)["counters"]["refused"]
    gained = {k: refused.get(k, 0) - before.get(k, 0) for k in refused}
    assert gained.get("bad message (schema)", 0) >= 60, refused


def test_cutting_the_link_to_a_controller_eases_the_head_to_neutral_within_1_s(net) -> None:  # type: ignore[no-untyped-def]
    tmp, nodes, _, _ = net
    node = nodes[1]
    code = f"""
import sys, time
from servoface.controller.network.client import HeadsClient
from servoface.controller.network.keys import head_keys
from servoface.controller.network.zconfig import Credentials, open_session
s = open_session(connect=["{node.endpoint}"], creds=Credentials("operator", "op-secret"))
c = HeadsClient(s, live=True)
{_until_ready("h2")}c.send(head_keys("lobby", "h2"), "express", name="surprise", transition_s=0.3, hold_s=30.0)
print("sent", flush=True)
time.sleep(60)
"""
    helper = _helper(tmp, code)
    assert helper.stdout is not None and helper.stdout.readline().strip() == "sent"
    rest_goals = node.wait_goals(BROW)
    assert rest_goals, "the node wrote no goals"
    rest_brow = rest_goals[0][1]
    sent = time.monotonic()

    def raised_and_settled() -> bool:  # the surprise (transition 0.3 s) is on the wire and held
        goals = node.goals(BROW, sent)
        return time.monotonic() - sent > 1.0 and bool(goals) and abs(goals[-1][1] - rest_brow) > 15

    assert _wait_for(raised_and_settled, 20.0), "the expression did not arrive"
    helper.send_signal(signal.SIGSTOP)  # the link goes silent (no FIN, no keep-alives): a cut cable
    cut = time.monotonic()
    try:

        def back_at_rest() -> list[float]:
            return [t for t, g in node.goals(BROW, cut) if abs(g - rest_brow) <= 2]

        back = _wait_for(back_at_rest, 10.0)
        assert back, f"brow never back at rest after the cut: {node.goals(BROW, cut)[-3:]}"
        print(f"link cut -> brow at rest after {(back[0] - cut) * 1e3:.0f} ms")
        # the goal (1 s) is measured by `servoface bench network`; here a bound a loaded CI machine keeps
        # (the expression holds for 30 s: without the cut-link rule the brow would stay raised)
        assert back[0] - cut <= 2.5
    finally:
        helper.send_signal(signal.SIGCONT)
        helper.kill()
        helper.wait(10)


def test_killing_a_node_removes_it_from_the_heads_list_within_1_s(net) -> None:  # type: ignore[no-untyped-def]
    _, nodes, client, _ = net
    node: NodeProc = nodes[2]
    node.proc.send_signal(signal.SIGKILL)
    t0 = time.monotonic()
    node.proc.wait(10)
    gone = None
    while time.monotonic() - t0 < 5.0:
        if "h3" not in [h.name for h in client.heads("lobby/*", timeout_s=0.3)]:
            gone = time.monotonic() - t0
            break
        time.sleep(0.05)
    assert gone is not None and gone <= 3.0, f"h3 still listed {gone}"


def test_a_cue_says_which_heads_took_it_and_which_refused(net, capsys) -> None:  # type: ignore[no-untyped-def]
    """Each head answers a cue (it publishes state/cue or state/refused with the cue's id); the sender, and
    `servoface cue`, say which refused and why. An e-stopped head refuses; `cue clear_estop` unlatches it.
    (The heads still up: another test of this module stops h3.)"""
    from servoface.controller.cli import main

    _, nodes, client, _ = net
    connect = [arg for n in nodes if n.proc.poll() is None for arg in ("--connect", n.endpoint)]
    connect += ["--user", "operator", "--password", "op-secret"]
    good = client.cue(
        "lobby/*", {"verb": "express", "name": "happiness", "hold_s": 0.2}, in_s=0.5, answers_within_s=5.0
    )
    live = sorted(good["heads"])
    assert "lobby/h1" in live and "lobby/h2" in live, good
    assert good["answers"] == {head: "accepted" for head in live}, good
    bad = client.cue("lobby/*", {"verb": "express", "name": "glee"}, in_s=0.5, answers_within_s=5.0)
    assert all(a.startswith("refused: ") and "glee" in a for a in bad["answers"].values()), bad
    # the command line: exit 1 and the reason on stderr for a refused cue
    assert main(["cue", "--heads", "lobby/*", "express", "glee", *connect]) == 1
    out, err = capsys.readouterr()
    assert f"taken by 0 of {len(live)} head(s)" in out and err.count("refused: ") == len(live), out + err
    # an e-stopped head refuses; clear_estop from the command line unlatches it
    client.estop("lobby/h2", reason="test")
    _wait_for(lambda: client.status(head_keys("lobby", "h2"), timeout_s=5.0).get("estop_latched"), 15.0)
    stopped = client.cue("lobby/*", {"verb": "neutral"}, in_s=0.5, answers_within_s=5.0)
    assert stopped["answers"]["lobby/h2"].startswith("refused: "), stopped
    assert stopped["answers"]["lobby/h1"] == "accepted", stopped
    assert main(["cue", "--heads", "lobby/h2", "clear_estop", *connect]) == 0
    assert _wait_for(lambda: client.status(head_keys("lobby", "h2"), timeout_s=5.0).get("estop_latched") is False, 15.0)
    capsys.readouterr()
    assert main(["cue", "--heads", "lobby/h1", "neutral", *connect]) == 0  # (h2's torque stays off until asked)
    assert "taken by 1 of 1 head(s)" in capsys.readouterr().out


def test_a_stopped_node_says_how_its_head_ended(net) -> None:  # type: ignore[no-untyped-def]
    """SIGTERM (a service manager's stop): the node's log ends with the head's stop report, as play's does."""
    _, nodes, _, _ = net
    node: NodeProc = nodes[0]
    node.stop()
    assert node.proc.returncode == 0
    log = node.log.read_text()
    assert "stopped;" in log and "eased to neutral" in log and "torque off on every servo" in log, log[-2000:]
