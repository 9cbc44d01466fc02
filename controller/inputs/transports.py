"""Receivers that feed a :class:`StreamSource` from a background thread: UDP datagrams (one JSON object
each), a TCP server on localhost (one JSON object per line), or any text stream such as stdin.

Every receiver binds to 127.0.0.1 by default; another address needs ``allow_remote=True`` (face data from
the network is an unauthenticated control channel to motors). Lines and datagrams larger than 64 KiB are
counted as bad. UDP and TCP receivers decode only the newest of the messages waiting at each read and
count the rest as superseded, so a sender faster than the decoder adds no lag. ``start()`` returns at
once, ``close()`` stops the thread and the socket (idempotent), and each receiver is a context manager.
``address`` is the bound (host, port) (port 0 picks a free one).
"""

from __future__ import annotations

import ipaddress
import socket
import threading
from types import TracebackType
from typing import IO, Any

from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.messages import MAX_MESSAGE_BYTES
from servoface.controller.inputs.stream import StreamSource

_POLL_S = 0.05


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


def check_host(host: str, allow_remote: bool) -> None:
    """Refuse a non-loopback bind address unless ``allow_remote``."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError as err:
        raise InputError(f"host {host!r}: expected an IP address such as 127.0.0.1") from err
    if not loopback and not allow_remote:
        raise InputError(
            f"host {host!r} is not a loopback address; binding it exposes motor control to the "
            f"network. Pass allow_remote=True (CLI: --allow-remote) to do so deliberately"
        )


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
        check_host(host, allow_remote)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
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
            skipped = 0
            try:  # drain what else is waiting: only the newest datagram matters (no backlog, no lag)
                self.sock.setblocking(False)
                while True:
                    data, peer = self.sock.recvfrom(MAX_MESSAGE_BYTES + 1)
                    skipped += 1
            except (BlockingIOError, InterruptedError):
                pass
            except OSError:
                break
            finally:
                if self.sock.fileno() >= 0:
                    self.sock.settimeout(_POLL_S)
            if skipped:
                self.source.supersede(skipped)
            self.source.feed(data, where=f"udp {peer[0]}:{peer[1]}")

    def close(self) -> None:
        super().close()
        self.sock.close()


class TcpReceiver(_Receiver):
    """A TCP server on ``host:port`` reading one JSON object per line, one client at a time."""

    name = "tcp"

    def __init__(
        self, source: StreamSource, host: str = "127.0.0.1", port: int = 9101, *, allow_remote: bool = False
    ) -> None:
        super().__init__(source)
        check_host(host, allow_remote)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, port))
            self.sock.listen(1)
        except OSError as err:
            self.sock.close()
            raise InputError(f"tcp {host}:{port}: cannot listen: {err}") from err
        self.sock.settimeout(_POLL_S)
        self.address = self.sock.getsockname()
        self.clients = 0

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, peer = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                break
            self.clients += 1
            with conn:
                conn.settimeout(_POLL_S)
                self._serve(conn, f"tcp {peer[0]}:{peer[1]}")

    def _serve(self, conn: socket.socket, where: str) -> None:
        pending = b""
        while not self._stop.is_set():
            try:
                chunk = conn.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            if not chunk:
                if pending.strip():
                    self.source.feed(pending, where=where)
                return
            pending += chunk
            *lines, pending = pending.split(b"\n")
            complete = [line for line in lines if line.strip()]
            if complete:  # only the newest complete line matters (no backlog, no lag)
                if len(complete) > 1:
                    self.source.supersede(len(complete) - 1)
                self.source.feed(complete[-1], where=where)
            if len(pending) > MAX_MESSAGE_BYTES:
                self.source.feed(pending, where=where)  # counted as bad (too long); resynchronise
                pending = b""

    def close(self) -> None:
        super().close()
        self.sock.close()


class LineReceiver(_Receiver):
    """One JSON object per line from a text stream (e.g. ``sys.stdin``); stops at end of file."""

    name = "lines"

    def __init__(self, source: StreamSource, stream: IO[str], *, where: str = "stdin") -> None:
        super().__init__(source)
        self.stream = stream
        self.where = where
        self.eof = threading.Event()

    def _run(self) -> None:
        try:
            for line in self.stream:
                if self._stop.is_set():
                    break
                if line.strip():
                    self.source.feed(line, where=self.where)
        finally:
            self.eof.set()

    def close(self) -> None:
        # a thread blocked in readline() cannot be interrupted portably; it is a daemon thread
        self._stop.set()
        if self._thread is not None and self.eof.is_set():
            self._thread.join(timeout=1.0)
