"""A TCP server for face-data streams: one JSON object per line, several clients at once, none of which can
hold the server hostage.

One thread serves every connection (``selectors``, non-blocking sockets), so a slow or silent client blocks
nobody. Rules (README "Inputs", "Stream server"):

* at most ``max_clients`` connections (default 4); a new one at the cap closes the connection that has been
  silent longest, never the controlling one (``evicted``);
* a connection silent for ``idle_timeout_s`` (default 10 s) is closed (``idle_closed``); with a token
  configured, one that has not sent its token line within ``auth_timeout_s`` (2 s) is too, and one whose first
  line lacks the token is closed at once (``unauthenticated``);
* lines are rate limited per connection and only the newest complete line of a read is decoded (the rest:
  ``superseded``); a line over 64 KiB is bad and the stream resynchronises at the next newline;
* the control rule of admission.py decides whose messages move the head; closing the controlling connection
  frees control at once.
"""

from __future__ import annotations

import itertools
import selectors
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.messages import MAX_MESSAGE_BYTES, parse_json
from servoface.controller.inputs.stream import StreamSource
from servoface.controller.inputs.transports import _POLL_S, _Receiver, check_host, network_guard

_ids = itertools.count(1)


@dataclass
class _Conn:
    sock: socket.socket
    where: str
    client: tuple[str, int]
    opened_s: float
    last_rx_s: float
    authenticated: bool
    pending: bytes = field(default=b"")


class TcpReceiver(_Receiver):
    """A TCP server on ``host:port`` (default 127.0.0.1:9101) reading one JSON object per line."""

    name = "tcp"

    def __init__(
        self,
        source: StreamSource,
        host: str = "127.0.0.1",
        port: int = 9101,
        *,
        allow_remote: bool = False,
        max_clients: int = 4,
        idle_timeout_s: float = 10.0,
        auth_timeout_s: float = 2.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__(source)
        self.guard = network_guard(source)
        check_host(host, allow_remote, self.guard.needs_token)
        if isinstance(max_clients, bool) or not isinstance(max_clients, int) or not 1 <= max_clients <= 1024:
            raise InputError(f"max_clients: expected 1..1024 connections, got {max_clients!r}")
        for name, value in (("idle_timeout_s", idle_timeout_s), ("auth_timeout_s", auth_timeout_s)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value <= 86_400:
                raise InputError(f"{name}: expected 0 < seconds <= 86400, got {value!r}")
        self.max_clients = max_clients
        self.idle_timeout_s = float(idle_timeout_s)
        self.auth_timeout_s = float(auth_timeout_s)
        self.clock = clock
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, port))
            self.sock.listen(16)
        except OSError as err:
            self.sock.close()
            raise InputError(f"tcp {host}:{port}: cannot listen: {err}") from err
        self.sock.setblocking(False)
        self.address: tuple[str, int] = self.sock.getsockname()
        self._conns: dict[socket.socket, _Conn] = {}

    @property
    def clients(self) -> int:
        """Connections accepted so far."""
        return self.guard.stats.connections

    @property
    def open_connections(self) -> int:
        return len(self._conns)

    def _run(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self.sock, selectors.EVENT_READ, None)
        try:
            while not self._stop.is_set():
                try:
                    events = sel.select(timeout=_POLL_S)
                except OSError:
                    break
                for key, _ in events:
                    if key.data is None:
                        self._accept(sel)
                    else:
                        self._read(sel, key.data)
                self._expire(sel)
        finally:
            for conn in list(self._conns.values()):
                self._close(sel, conn)
            sel.close()

    def _accept(self, sel: selectors.BaseSelector) -> None:
        try:
            sock, peer = self.sock.accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self._stop.set()
            return
        sock.setblocking(False)
        now = self.clock()
        if len(self._conns) >= self.max_clients:
            controller = self.guard.controller
            others = [c for c in self._conns.values() if c.client != controller]
            if others:
                self._close(sel, min(others, key=lambda c: c.last_rx_s))
                self.guard.count("evicted")
        conn = _Conn(sock, f"tcp {peer[0]}:{peer[1]}", ("tcp", next(_ids)), now, now, not self.guard.needs_token)
        self._conns[sock] = conn
        sel.register(sock, selectors.EVENT_READ, conn)
        self.guard.count("connections")

    def _read(self, sel: selectors.BaseSelector, conn: _Conn) -> None:
        try:
            chunk = conn.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            chunk = b""
        if not chunk:
            if conn.pending.strip() and conn.authenticated:
                self.source.feed(conn.pending, where=conn.where, client=conn.client, authenticated=True)
            self._close(sel, conn)
            return
        conn.last_rx_s = self.clock()
        conn.pending += chunk
        *lines, conn.pending = conn.pending.split(b"\n")
        complete = [line for line in lines if line.strip()]
        if not conn.authenticated and complete:
            if not self._authenticate(conn, complete[0]):
                self._close(sel, conn)
                return
            complete = complete[1:] if _token_only(complete[0]) else complete
        passed = [line for line in complete if self.source.rate_ok(conn.client)]
        if passed:  # only the newest complete line matters (no backlog, no lag)
            if len(passed) > 1:
                self.source.supersede(len(passed) - 1)
            self.source.feed(passed[-1], where=conn.where, client=conn.client, authenticated=True, rate_checked=True)
        if len(conn.pending) > MAX_MESSAGE_BYTES:
            self.guard.count("lines_too_long")
            self.source.feed(conn.pending[: MAX_MESSAGE_BYTES + 1], where=conn.where, client=conn.client)
            conn.pending = b""  # counted as bad (too long); resynchronise at the next newline

    def _authenticate(self, conn: _Conn, first: bytes) -> bool:
        try:
            obj = parse_json(first, where=conn.where)
        except InputError:
            obj = None
        conn.authenticated = self.guard.token_ok(obj)
        return conn.authenticated

    def _expire(self, sel: selectors.BaseSelector) -> None:
        now = self.clock()
        for conn in list(self._conns.values()):
            silent = now - conn.last_rx_s > self.idle_timeout_s
            no_token = not conn.authenticated and now - conn.opened_s > self.auth_timeout_s
            if silent or no_token:
                self.guard.count("idle_closed")
                self._close(sel, conn)

    def _close(self, sel: selectors.BaseSelector, conn: _Conn) -> None:
        self._conns.pop(conn.sock, None)
        try:
            sel.unregister(conn.sock)
        except (KeyError, ValueError, OSError):
            pass
        conn.sock.close()
        self.guard.release(conn.client)

    def close(self) -> None:
        super().close()
        self.sock.close()


def _token_only(line: bytes) -> bool:
    """The line is a bare ``{"token": ...}`` hello (nothing to decode after authenticating)."""
    try:
        obj = parse_json(line)
    except InputError:
        return False
    return isinstance(obj, dict) and set(obj) == {"token"}
