"""The envelope, the sequence guard, the key space and the endpoint rules (no network needed)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from servoface.controller.network.errors import InsecureEndpointError, MessageError, NetworkError
from servoface.controller.network.keys import head_keys, parse_head_key, pattern_keys
from servoface.controller.network.messages import SequenceGuard, envelope, open_envelope
from servoface.controller.network.zconfig import Credentials, TlsFiles, check_endpoints, is_loopback


def test_envelope_round_trip_and_refusals() -> None:
    seq, body = open_envelope(envelope({"t": 1.0, "aus": {"AU12": 0.5}}, 7))
    assert seq == 7 and body == {"t": 1.0, "aus": {"AU12": 0.5}}
    for raw, field in [
        (json.dumps({"schema": 2, "seq": 1}).encode(), "schema"),
        (json.dumps({"seq": 1}).encode(), "schema"),
        (json.dumps({"schema": True, "seq": 1}).encode(), "schema"),
        (json.dumps({"schema": 1, "seq": -1}).encode(), "seq"),
        (json.dumps({"schema": 1, "seq": "3"}).encode(), "seq"),
        (json.dumps([1, 2]).encode(), "object"),
        (b"[" * 5000, "message"),
        (b"\xff\xfe", "message"),
        (b"x" * 70_000, "bytes"),
    ]:
        with pytest.raises(MessageError, match=field):
            open_envelope(raw)


def test_sequence_guard_refuses_stale_and_out_of_order_but_takes_a_restart() -> None:
    g = SequenceGuard()
    assert g.take("a", "k", 1) and g.take("a", "k", 2)
    assert not g.take("a", "k", 2) and not g.take("a", "k", 1)  # duplicate, out of order
    assert g.take("b", "k", 1) and g.take("a", "other", 1)  # per sender and key
    assert g.take("a", "k", 5000) and g.take("a", "k", 3)  # a jump back > 1000: the sender restarted
    assert g.counters()["refused"] == {"stale or out of order": 2}


@pytest.mark.parametrize("bad", ["", "Lobby", "a/b", "*", "a*", "$x", "x" * 41, "a?b", "-a"])
def test_site_and_name_are_plain_tokens(bad: str) -> None:
    with pytest.raises(NetworkError, match="site"):
        head_keys(bad, "ada")


def test_keys_and_patterns() -> None:
    k = head_keys("lobby", "ada")
    assert k.aus("stream") == "servoface/lobby/ada/aus/stream" and k.presence == "@servoface/lobby/ada"
    assert parse_head_key("@servoface/lobby/ada") == ("lobby", "ada") and parse_head_key("x/y") is None
    assert pattern_keys("lobby/*").base == "servoface/lobby/*"
    with pytest.raises(NetworkError):
        pattern_keys("lobby/**")


def test_loopback_detection() -> None:
    assert is_loopback("tcp/127.0.0.1:7447") and is_loopback("tcp/[::1]:7447") and is_loopback("tcp/localhost:1")
    assert not is_loopback("tcp/10.0.0.7:7447") and not is_loopback("tls/robot.local:7447")


def test_an_endpoint_beyond_loopback_needs_tls_and_credentials_or_insecure() -> None:
    with pytest.raises(InsecureEndpointError, match="tls"):
        check_endpoints(["tcp/0.0.0.0:7447"], [], Credentials(), TlsFiles(), insecure=False)
    with pytest.raises(InsecureEndpointError, match="credentials"):
        check_endpoints(["tls/0.0.0.0:7447"], [], Credentials(), TlsFiles("ca.pem", "c.pem", "k.pem"), insecure=False)  # type: ignore[arg-type]
    check_endpoints(
        ["tls/0.0.0.0:7447"],
        [],
        Credentials(users_file="u.txt"),
        TlsFiles("ca.pem", "c.pem", "k.pem"),  # type: ignore[arg-type]
        insecure=False,
    )
    check_endpoints(["tcp/0.0.0.0:7447"], [], Credentials(), TlsFiles(), insecure=True)
    check_endpoints(["tcp/127.0.0.1:7447"], ["tcp/127.0.0.1:7448"], Credentials(), TlsFiles(), insecure=False)
    with pytest.raises(NetworkError, match="endpoint"):
        check_endpoints(["127.0.0.1:7447"], [], Credentials(), TlsFiles(), insecure=False)


def test_the_node_cli_refuses_an_open_endpoint_without_insecure() -> None:
    from servoface.controller.cli import main

    assert main(["node", "--name", "ada", "--emulate", "--listen", "tcp/0.0.0.0:17999"]) == 2


def test_speech_commands_go_to_the_slow_worker_and_nothing_else_does() -> None:
    """Synthesis takes ~0.1 s: a ``say`` (or a ``cue`` of one) must not run on Zenoh's callback thread, where AU
    frames would wait behind it; every other command, malformed ones included, stays on the fast path."""
    from servoface.controller.network.node import needs_synthesis

    assert needs_synthesis("say", {"text": "hello"})
    assert needs_synthesis("cue", {"what": {"verb": "say", "text": "hello"}, "at_s": 1.0})
    assert not needs_synthesis("cue", {"what": {"verb": "express", "name": "joy"}, "at_s": 1.0})
    assert not needs_synthesis("cue", {"what": "say"})
    assert not needs_synthesis("cue", {})
    assert not needs_synthesis("express", {"name": "joy", "what": {"verb": "say"}})


def test_tls_files_are_used_and_are_pem_files_of_their_kind(tmp_path: Path) -> None:
    """TLS files with no tls/ endpoint were silently unused (a plain tcp/ link, believed encrypted); a file
    that is not PEM reached Zenoh, whose refusal is a Rust backtrace naming no flag."""
    from servoface.controller.network.zconfig import session_config

    from tests.controller.network.certs import make_tls

    real = make_tls(tmp_path)
    tls = TlsFiles(real.ca, real.cert, real.key)
    with pytest.raises(NetworkError, match=r"--tls-ca/--tls-cert/--tls-key given, but no tls/ or quic/ endpoint"):
        session_config(listen=["tcp/127.0.0.1:7447"], tls=tls)
    with pytest.raises(NetworkError, match=r"--tls-ca given, but no tls/"):
        session_config(connect=["tcp/127.0.0.1:7447"], tls=TlsFiles(real.ca))
    (tmp_path / "junk.bin").write_bytes(b"\xff\xfe\x00junk")
    tls_ep = ["tls/127.0.0.1:7447"]
    with pytest.raises(NetworkError, match=r"--tls-ca .*junk\.bin: not a PEM certificate"):
        session_config(listen=tls_ep, tls=TlsFiles(tmp_path / "junk.bin", real.cert, real.key))
    with pytest.raises(NetworkError, match=r"--tls-key .*: not a PEM private key"):
        session_config(listen=tls_ep, tls=TlsFiles(real.ca, real.cert, real.cert))
    with pytest.raises(NetworkError, match=r"--tls-cert .*nothere\.pem: not found"):
        session_config(listen=tls_ep, tls=TlsFiles(real.ca, tmp_path / "nothere.pem", real.key))
    session_config(listen=tls_ep, tls=tls)  # the real set passes


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (b"\xff\xfe\x00", r"not UTF-8 text \(byte 0\)"),
        (b"alice:pw\nbob\n", r"line 2: expected lines 'user:password'"),
        (b":nobody\n", r"line 1: expected lines 'user:password'"),
        (b"\n\n", r"no users"),
    ],
)
def test_a_users_file_zenoh_cannot_read_is_named_with_its_line(tmp_path: Path, body: bytes, message: str) -> None:
    from servoface.controller.network.zconfig import session_config

    users = tmp_path / "users.txt"
    users.write_bytes(body)
    with pytest.raises(NetworkError, match=message):
        session_config(listen=["tcp/127.0.0.1:7447"], creds=Credentials(users_file=users))
    users.write_text("alice:pw\n\nbob:secret\n")
    session_config(listen=["tcp/127.0.0.1:7447"], creds=Credentials(users_file=users))
