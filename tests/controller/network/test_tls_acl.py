"""A node over TLS with real certificates (a throwaway CA made here), user/password authentication and
Zenoh access control (``--operators``), in its own process on loopback; what reaches the head is read
from its emulator's side of the wire."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from servoface.controller.network.acl import node_acl, parse_operators
from servoface.controller.network.client import HeadsClient
from servoface.controller.network.errors import NetworkError
from servoface.controller.network.keys import head_keys
from servoface.controller.network.testbed import NodeProc, start_nodes
from servoface.controller.network.zconfig import Credentials, TlsFiles, open_session, session_config
from servoface.sim.heads import load_head

from tests.controller.network.certs import TlsSet, make_tls

HEAD = load_head("human")
BROW = HEAD.servo_ids["brow_inner_l"]
JAW = HEAD.servo_ids["jaw"]
KEYS = head_keys("lobby", "t1")


def _moved_after(node: NodeProc, since_s: float, rest: int, *, wait_s: float) -> bool:
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        if any(abs(g - rest) >= 5 for _, g in node.goals(BROW, since_s)):
            return True
        time.sleep(0.1)
    return False


def _rest(node: NodeProc) -> int:
    goals = node.wait_goals(BROW)
    assert goals, f"the node wrote no goals in 20 s: {node.log.read_text()[-2000:]}"
    return goals[-1][1]


def _client(endpoint: str, user: str, password: str, ca: Path) -> tuple[object, HeadsClient]:
    session = open_session(connect=[endpoint], creds=Credentials(user, password), tls=TlsFiles(ca))
    return session, HeadsClient(session)


def _status(client: HeadsClient, timeout_s: float = 20.0) -> dict:  # type: ignore[type-arg]
    """The head's status; `HeadsClient.status` gives {} when no reply came within its 1 s (a loaded
    machine, a Zenoh link re-forming): asked again until one does."""
    deadline = time.monotonic() + timeout_s
    while not (status := client.status(KEYS)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert status, "the node gave no status"
    return status


def _wait_heads(client: HeadsClient, n: int, timeout_s: float = 30.0) -> list:  # type: ignore[type-arg]
    deadline = time.monotonic() + timeout_s
    heads: list = []  # type: ignore[type-arg]
    while time.monotonic() < deadline:
        heads = client.heads("lobby/*")
        if len(heads) >= n:
            break
        time.sleep(0.3)
    return heads


@pytest.fixture(scope="module")
def tls_node(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    tmp = tmp_path_factory.mktemp("zenoh-tls")
    tls = make_tls(tmp / "pki")
    users = tmp / "users.txt"
    users.write_text("operator:op-secret\nguard:guard-secret\nnode:node-secret\n")
    extra = ["--tls-ca", str(tls.ca), "--tls-cert", str(tls.cert), "--tls-key", str(tls.key)]
    nodes = start_nodes(tmp, ["t1"], users_file=users, proto="tls", extra=[*extra, "--operators", "operator"])
    try:
        yield tmp, tls, nodes[0]
    finally:
        nodes[0].stop()


@pytest.mark.slow
def test_an_operator_over_tls_sees_and_moves_the_head(tls_node) -> None:  # type: ignore[no-untyped-def]
    tmp, tls, node = tls_node
    assert node.endpoint.startswith("tls/")
    session, client = _client(node.endpoint, "operator", "op-secret", tls.ca)
    try:
        heads = _wait_heads(client, 1)
        assert [h.name for h in heads] == ["t1"] and _status(client)["running"]
        rest, since = _rest(node), time.monotonic()
        client.send(KEYS, "express", name="surprise", transition_s=0.2, hold_s=0.5)
        assert _moved_after(node, since, rest, wait_s=10.0), "the operator's command did not reach the head"
        client.send(KEYS, "neutral", transition_s=0.2)
        time.sleep(1.0)
    finally:
        session.close()  # type: ignore[attr-defined]


@pytest.mark.slow
def test_an_operator_makes_the_head_talk(tls_node) -> None:  # type: ignore[no-untyped-def]
    """cmd/say: synthesised off Zenoh's callback thread, played on the speech track (jaw budgeted)."""
    tmp, tls, node = tls_node
    session, client = _client(node.endpoint, "operator", "op-secret", tls.ca)
    try:
        assert _wait_heads(client, 1)
        goals = node.wait_goals(JAW)
        assert goals, f"the node wrote no goals in 20 s: {node.log.read_text()[-2000:]}"
        rest, since = goals[-1][1], time.monotonic()
        client.send(KEYS, "say", text="Hello, how are you today?")
        deadline = time.monotonic() + 15
        swing = 0
        while time.monotonic() < deadline and swing < 20:
            swing = max([abs(g - rest) for _, g in node.goals(JAW, since)] or [0])
            time.sleep(0.2)
        assert swing >= 20, f"the jaw did not talk ({swing} ticks)"
    finally:
        session.close()  # type: ignore[attr-defined]


@pytest.mark.slow
def test_a_peer_trusting_another_ca_gets_no_link(tls_node) -> None:  # type: ignore[no-untyped-def]
    tmp, tls, node = tls_node
    other: TlsSet = make_tls(tmp / "other-pki", "someone-else")
    session, client = _client(node.endpoint, "operator", "op-secret", other.ca)  # right password, wrong CA
    try:
        rest, since = _rest(node), time.monotonic()
        assert client.heads("lobby/*", timeout_s=1.0) == []
        client.send(KEYS, "express", name="surprise", transition_s=0.2, hold_s=0.5)
        assert not _moved_after(node, since, rest, wait_s=1.5), "a peer with an untrusted certificate moved the head"
    finally:
        session.close()  # type: ignore[attr-defined]
    # and plain TCP to the TLS port: no session either
    tcp = node.endpoint.replace("tls/", "tcp/")
    try:
        plain = open_session(connect=[tcp], creds=Credentials("operator", "op-secret"))
    except NetworkError:
        return
    try:
        assert HeadsClient(plain).heads("lobby/*", timeout_s=1.0) == []
    finally:
        plain.close()


@pytest.mark.slow
def test_an_observer_reads_and_can_stop_but_cannot_move(tls_node) -> None:  # type: ignore[no-untyped-def]
    tmp, tls, node = tls_node
    g_session, guard = _client(node.endpoint, "guard", "guard-secret", tls.ca)
    o_session, operator = _client(node.endpoint, "operator", "op-secret", tls.ca)
    try:
        heads = _wait_heads(guard, 1)
        assert [h.name for h in heads] == ["t1"], "an observer may see presence and status"
        accepted = _status(guard)["counters"]["accepted"]
        rest, since = _rest(node), time.monotonic()
        guard.send(KEYS, "express", name="surprise", transition_s=0.2, hold_s=0.5)
        for _ in range(10):
            guard.send_aus(KEYS, {"AU1": 1.0, "AU2": 1.0, "AU26": 0.8})
            time.sleep(0.02)
        assert not _moved_after(node, since, rest, wait_s=1.5), "an observer's command or AU frames moved the head"
        after = _status(guard)
        assert after["counters"]["accepted"] == accepted, "Zenoh should drop them before the node sees them"
        guard.estop("lobby/*", reason="guard pressed stop")  # a pattern: allowed by servoface-estop
        deadline = time.monotonic() + 10
        while not _status(guard).get("estop_latched") and time.monotonic() < deadline:
            time.sleep(0.1)
        assert _status(guard)["estop_latched"], "the observer's e-stop was not honoured"
        guard.send(KEYS, "clear_estop")
        time.sleep(1.0)
        assert _status(guard)["estop_latched"], "an observer must not clear the e-stop"
        operator.send(KEYS, "clear_estop")
        deadline = time.monotonic() + 10
        while _status(guard).get("estop_latched") and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _status(guard)["estop_latched"], "the operator could not clear the e-stop"
    finally:
        g_session.close()  # type: ignore[attr-defined]
        o_session.close()  # type: ignore[attr-defined]


def test_operators_are_plain_tokens_and_need_a_users_file(tmp_path: Path) -> None:
    assert parse_operators("ada, bob") == ("ada", "bob")
    with pytest.raises(NetworkError, match="operators"):
        parse_operators("ada,*")
    with pytest.raises(NetworkError, match="operators"):
        parse_operators(" , ")
    with pytest.raises(NetworkError, match="users-file"):
        session_config(listen=["tcp/127.0.0.1:7447"], acl=node_acl(KEYS, ["ada"]))
    rules = {r["id"]: r for r in node_acl(KEYS, ["ada"])["rules"]}
    assert rules["servoface-control"]["key_exprs"][0] == "servoface/lobby/t1/aus/*"
    assert node_acl(KEYS, ["ada"])["default_permission"] == "deny"
