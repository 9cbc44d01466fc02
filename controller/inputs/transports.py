"""Receivers that feed a :class:`StreamSource` from a background thread: UDP datagrams (one JSON object
each), a TCP server (tcp_server.py: one JSON object per line, several clients), or any text stream such as
stdin (optionally paced by the messages' own ``t``).

Every network receiver binds to 127.0.0.1 by default; another address needs ``allow_remote=True`` AND a
shared token on the source's guard (face data from the network is a control channel to motors). Network
receivers always have a :class:`~servoface.controller.inputs.admission.StreamGuard` (one is made if the
source has none): rate limit per client, one controlling client, the token if set. Lines and datagrams
larger than 64 KiB are counted as bad. Of the datagrams waiting at one read, each client's newest is
decoded and the rest are counted as superseded (a fast sender adds no lag, and a flooding client cannot
push another client's newest message out). ``start()`` returns at once, ``close()`` stops the thread and the
socket (idempotent), and each receiver is a context manager. ``address`` is the bound (host, port) (port 0
picks a free one).
"""

from __future__ import annotations

import ipaddress
import math
import socket
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import IO, Any

from servoface.controller.inputs.admission import StreamGuard
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.messages import MAX_MESSAGE_BYTES, parse_json
from servoface.controller.inputs.stream import RESTART_S, StreamSource

_POLL_S = 0.05
_RCVBUF_BYTES = 4 << 20  # room for a flood's datagrams so a second client's are not dropped by the kernel
_MAX_BATCH = 4096  # datagrams drained per read before the newest of each client is decoded
MAX_GAP_S = 10.0  # pacing: a forward jump in t beyond this is a pause, not a wait


def parse_address(text: str, *, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``"127.0.0.1:9100"`` or ``"9100"`` -> (host, port); InputError naming the text if malformed."""
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = default_host, text
    try:
        port = int(port_text)
    except ValueError as err:
        raise InputError(f"address {text!r}: expected HOST:PORT or PORT with a numeric port") from err
    if not 0 <= port <= 65535:
        raise InputError(f"address {text!r}: port {port} is outside 0..65535")
    return host or default_host, port


def check_host(host: str, allow_remote: bool, has_token: bool = True) -> None:
    """Refuse a non-loopback bind address unless ``allow_remote`` and a token is configured."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError as err:
        raise InputError(f"host {host!r}: expected an IP address such as 127.0.0.1") from err
    if not loopback and not allow_remote:
        raise InputError(
            f"host {host!r} is not a loopback address; binding it exposes motor control to the "
            f"network. Pass allow_remote=True (CLI: --allow-remote) to do so deliberately"
        )
    if not loopback and not has_token:
        raise InputError(
            f"host {host!r} is not a loopback address: a shared token is required to listen there "
            "(StreamGuard(token=...); CLI: --token-file FILE or --token-env VAR)"
        )


def network_guard(source: StreamSource) -> StreamGuard:
    """The source's guard, made (no token, default limits) if it has none."""
    if source.guard is None:
        source.guard = StreamGuard()
    return source.guard


class _Receiver:
    name = "receiver"

    def __init__(self, source: StreamSource) -> None:
        self.source = source
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> _Receiver:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"servoface-{self.name}", daemon=True)
            self._thread.start()
        return self

    def _run(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def __enter__(self) -> Any:
        return self.start()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class UdpReceiver(_Receiver):
    """One JSON object per datagram on ``host:port`` (default 127.0.0.1:9100)."""

    name = "udp"

    def __init__(
        self, source: StreamSource, host: str = "127.0.0.1", port: int = 9100, *, allow_remote: bool = False
    ) -> None:
        super().__init__(source)
        self.guard = network_guard(source)
        check_host(host, allow_remote, self.guard.needs_token)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, _RCVBUF_BYTES)
            self.sock.bind((host, port))
        except OSError as err:
            self.sock.close()
            raise InputError(f"udp {host}:{port}: cannot bind: {err}") from err
        self.sock.settimeout(_POLL_S)
        self.address: tuple[str, int] = self.sock.getsockname()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, peer = self.sock.recvfrom(MAX_MESSAGE_BYTES + 1)
            except TimeoutError:
                continue
            except OSError:
                break
            newest: dict[tuple[str, int], bytes] = {peer: data}
            counts: dict[tuple[str, int], int] = {peer: 1}
            try:  # drain what else is waiting: per client only the newest datagram matters (no backlog)
                self.sock.setblocking(False)
                recv = self.sock.recvfrom
                for _ in range(_MAX_BATCH):
                    data, peer = recv(MAX_MESSAGE_BYTES + 1)
                    newest[peer] = data
                    counts[peer] = counts.get(peer, 0) + 1
            except (BlockingIOError, InterruptedError):
                pass
            except OSError:
                break
            finally:
                if self.sock.fileno() >= 0:
                    self.sock.settimeout(_POLL_S)
            for peer, datagram in newest.items():  # the rate limit per client, on the whole batch at once
                client = ("udp", peer)
                if self.source.admit(client, counts[peer]):
                    self.source.feed(datagram, where=f"udp {peer[0]}:{peer[1]}", client=client, rate_checked=True)

    def close(self) -> None:
        super().close()
        self.sock.close()


class LineReceiver(_Receiver):
    """One JSON object per line from a text stream (e.g. ``sys.stdin``); stops at end of file.

    ``pace=True``: each message is fed when its own ``t`` (or MediaPipe ``timestamp_ms``) comes due, measured
    from the first message (``cat take.jsonl | servoface stream --stdin`` plays at the take's speed, not
    in a burst); lines without a time, and bad lines, pass at once. A time that jumps back more than
    ``RESTART_S`` or forward more than ``MAX_GAP_S`` re-anchors the pacing (a restarted sender, a pause).
    ``pace=False`` feeds each line as it arrives (a live pipe from a tracker)."""

    name = "lines"

    def __init__(
        self,
        source: StreamSource,
        stream: IO[str],
        *,
        where: str = "stdin",
        pace: bool = False,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__(source)
        self.stream = stream
        self.where = where
        self.pace = pace
        self.clock = clock
        self.eof = threading.Event()

    def _run(self) -> None:
        anchor: tuple[float, float] | None = None  # (message t, clock) the pacing counts from
        last_t: float | None = None
        try:
            for line in self.stream:
                if self._stop.is_set():
                    break
                if not line.strip():
                    continue
                t = message_time(line) if self.pace else None
                if t is not None:
                    now = self.clock()
                    back = last_t is not None and t < last_t - RESTART_S
                    if anchor is None or back or t - anchor[0] - (now - anchor[1]) > MAX_GAP_S:
                        anchor = (t, now)
                    wait_s = anchor[1] + (t - anchor[0]) - now
                    if wait_s > 0 and self._stop.wait(wait_s):
                        break
                    last_t = t
                self.source.feed(line, where=self.where)
        finally:
            self.eof.set()

    def close(self) -> None:
        # a thread blocked in readline() cannot be interrupted portably; it is a daemon thread
        self._stop.set()
        if self._thread is not None and self.eof.is_set():
            self._thread.join(timeout=1.0)


def message_time(line: str | bytes) -> float | None:
    """A message's own time in seconds (``t``, or MediaPipe's ``timestamp_ms`` / 1000), None if it has none
    or is not a readable message."""
    try:
        obj = parse_json(line)
    except InputError:
        return None
    if not isinstance(obj, dict):
        return None
    value, scale = (obj.get("t"), 1.0) if "t" in obj else (obj.get("timestamp_ms"), 1e-3)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value) * scale


from servoface.controller.inputs.tcp_server import TcpReceiver  # noqa: E402 - re-exported here

__all__ = ["LineReceiver", "TcpReceiver", "UdpReceiver", "check_host", "message_time", "parse_address"]
