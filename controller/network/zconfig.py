"""Zenoh configuration for servoface: explicit endpoints, no discovery by multicast, short leases.

Defaults that avoid what hurt other robot fleets (multicast discovery that fails on Wi-Fi and WSL and lets
robots hear each other): multicast scouting and gossip are **off**; a node listens where it is told
(``tcp/127.0.0.1:7447`` by default) and clients connect to it, or both connect to a router. Links use a
short lease (400 ms, 4 keep-alives per lease), so a dead or cut-off peer is noticed within half a second.

Beyond loopback, a node refuses to listen or connect without **TLS** (``tls/`` endpoints with a CA and a
certificate/key) and **user/password authentication** (a dictionary file of ``user:password`` lines for a
node, ``--user``/``--password`` for a client) unless ``insecure=True`` (``--insecure``). A peer without the
configured credentials cannot open a session with the node, so it can neither move the head nor read it.
"""

from __future__ import annotations

import ipaddress
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servoface.controller.network.errors import InsecureEndpointError, NetworkError

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
LEASE_MS = 400


@dataclass(frozen=True)
class Credentials:
    """What a session proves (user/password) and, for a node, whom it accepts (a dictionary file)."""

    user: str | None = None
    password: str | None = None
    users_file: Path | None = None

    @property
    def any(self) -> bool:
        return bool(self.user or self.users_file)


@dataclass(frozen=True)
class TlsFiles:
    root_ca: Path | None = None
    cert: Path | None = None
    key: Path | None = None


def _host(endpoint: str) -> tuple[str, str]:
    """(protocol, host) of a Zenoh endpoint such as ``tcp/127.0.0.1:7447`` or ``tls/[::1]:7447``."""
    if not isinstance(endpoint, str) or "/" not in endpoint:
        raise NetworkError(f"endpoint {endpoint!r:.60}: expected PROTO/HOST:PORT, e.g. {DEFAULT_LISTEN}")
    proto, rest = endpoint.split("/", 1)
    if proto not in ("tcp", "tls", "udp", "quic", "ws"):
        raise NetworkError(f"endpoint {endpoint!r}: unknown protocol {proto!r} (tcp, tls, udp, quic, ws)")
    host = rest.split("#", 1)[0]
    host = host[1 : host.index("]")] if host.startswith("[") else host.rsplit(":", 1)[0]
    return proto, host


def is_loopback(endpoint: str) -> bool:
    _, host = _host(endpoint)
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name: assume it is reachable from elsewhere


def check_endpoints(
    listen: Sequence[str], connect: Sequence[str], creds: Credentials, tls: TlsFiles, *, insecure: bool
) -> None:
    """Refuse an endpoint beyond loopback without TLS and credentials (unless ``insecure``)."""
    for endpoint in (*listen, *connect):
        proto, _ = _host(endpoint)
        if is_loopback(endpoint) or insecure:
            continue
        missing = []
        if proto not in ("tls", "quic"):
            missing.append("a tls/ (or quic/) endpoint")
        if tls.root_ca is None or (endpoint in listen and (tls.cert is None or tls.key is None)):
            missing.append("--tls-ca (and --tls-cert/--tls-key to listen)")
        if not creds.any:
            missing.append("credentials (--users-file on a node, --user/--password on a client)")
        if missing:
            raise InsecureEndpointError(
                f"endpoint {endpoint} is not on loopback: it needs {', '.join(missing)}; "
                "or pass --insecure (anyone who can reach it could move the head)"
            )


def session_config(
    *,
    listen: Sequence[str] = (),
    connect: Sequence[str] = (),
    creds: Credentials = Credentials(),
    tls: TlsFiles = TlsFiles(),
    insecure: bool = False,
    lease_ms: int = LEASE_MS,
    acl: dict[str, Any] | None = None,
) -> Any:
    """A ``zenoh.Config`` for a peer with these endpoints (validated first); ``acl``: an
    ``access_control`` section (:func:`.acl.node_acl`), which needs the users file (its subjects are user
    names)."""
    check_endpoints(listen, connect, creds, tls, insecure=insecure)
    check_tls_files(listen, connect, tls)
    if acl is not None and creds.users_file is None:
        raise NetworkError("access control (--operators) needs --users-file: its rules name authenticated users")
    import zenoh

    conf = zenoh.Config()

    def put(key: str, value: object) -> None:
        conf.insert_json5(key, json.dumps(value))

    put("mode", "peer")
    put("scouting/multicast/enabled", False)
    put("scouting/gossip/enabled", False)
    put("listen/endpoints", list(listen))
    put("connect/endpoints", list(connect))
    put("transport/link/tx/lease", int(lease_ms))
    put("transport/link/tx/keep_alive", 4)
    if creds.user is not None:
        put("transport/auth/usrpwd/user", creds.user)
        put("transport/auth/usrpwd/password", creds.password or "")
    if creds.users_file is not None:
        check_users_file(Path(creds.users_file))
        put("transport/auth/usrpwd/dictionary_file", str(creds.users_file))
    if tls.root_ca is not None:
        put("transport/link/tls/root_ca_certificate", str(tls.root_ca))
    if tls.cert is not None and tls.key is not None:
        put("transport/link/tls/listen_certificate", str(tls.cert))
        put("transport/link/tls/listen_private_key", str(tls.key))
    if acl is not None:
        put("access_control", acl)
    return conf


def _refusal(where: str) -> Callable[[str], NetworkError]:
    """The error for a file the bounded reader refuses: ``NetworkError("WHERE: reason")``."""
    return lambda reason: NetworkError(f"{where}: {reason}")


def check_users_file(path: Path) -> None:
    """A users file (``--users-file``) Zenoh can read: a regular file of at most 1 MiB, UTF-8 text of
    ``user:password`` lines, at least one (Zenoh's own refusal of a bad one is a Rust backtrace naming no
    line; a FIFO would be drained by this check before Zenoh reads it)."""
    from servoface.sim.textfile import SMALL_LIMIT_BYTES, read_bounded

    expected = "expected lines 'user:password'"
    try:
        raw = read_bounded(
            path,
            _refusal(f"users file {path}"),
            what="a users file",
            limit_bytes=SMALL_LIMIT_BYTES,
        )
        text = raw.decode("utf-8")
    except FileNotFoundError:
        raise NetworkError(f"users file {path}: not found ({expected})") from None
    except UnicodeDecodeError as err:
        raise NetworkError(f"users file {path}: not UTF-8 text (byte {err.start}); {expected}") from None
    except OSError as err:
        raise NetworkError(f"users file {path}: cannot read ({err.strerror or err}); {expected}") from None
    users = 0
    for n, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        user, sep, _ = line.partition(":")
        if not sep or not user.strip():
            raise NetworkError(f"users file {path}: line {n}: {expected}")
        users += 1
    if not users:
        raise NetworkError(f"users file {path}: no users ({expected})")


_PEM = {
    "root_ca": ("--tls-ca", "CERTIFICATE"),
    "cert": ("--tls-cert", "CERTIFICATE"),
    "key": ("--tls-key", "PRIVATE KEY"),
}


def check_tls_files(listen: Sequence[str], connect: Sequence[str], tls: TlsFiles) -> None:
    """TLS files that are given are used and usable: some endpoint is ``tls/`` or ``quic/`` (else the files
    would be silently ignored on a plain ``tcp/`` link, and whoever passed them would believe the link
    encrypted), and each is a readable PEM file of its kind (a certificate, a private key), a regular file of
    at most 1 MiB. The files' own validity (chain, expiry, key match) is Zenoh's to judge when it listens or
    connects."""
    from servoface.sim.textfile import SMALL_LIMIT_BYTES, read_bounded

    given = {name: getattr(tls, name) for name in _PEM if getattr(tls, name) is not None}
    if not given:
        return
    flags = "/".join(_PEM[name][0] for name in given)
    if not any(_host(e)[0] in ("tls", "quic") for e in (*listen, *connect)):
        where = ", ".join([*listen, *connect]) or "none"
        raise NetworkError(
            f"{flags} given, but no tls/ or quic/ endpoint would use them (endpoints: {where}); listen on "
            "or connect to a tls/HOST:PORT endpoint (--listen / --connect), or leave the TLS files out"
        )
    for name, path in given.items():
        flag, kind = _PEM[name]
        try:
            data = read_bounded(
                path, _refusal(f"{flag} {path}"), what=f"a PEM {kind.lower()} file", limit_bytes=SMALL_LIMIT_BYTES
            )
        except FileNotFoundError:
            raise NetworkError(f"{flag} {path}: not found (expected a PEM file)") from None
        except OSError as err:
            raise NetworkError(f"{flag} {path}: cannot read ({err.strerror or err})") from None
        if b"-----BEGIN " not in data or f"{kind}-----".encode() not in data:
            raise NetworkError(
                f"{flag} {path}: not a PEM {kind.lower()} (expected a '-----BEGIN ...{kind}-----' block)"
            )


def open_session(**kwargs: Any) -> Any:
    """``zenoh.open`` of :func:`session_config`; NetworkError with the endpoint if it cannot listen."""
    import zenoh

    conf = session_config(**kwargs)
    try:
        return zenoh.open(conf)
    except zenoh.ZError as err:
        raise NetworkError(f"cannot open a Zenoh session ({err}); is the endpoint in use or unreachable?") from err
