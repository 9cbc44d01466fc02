"""Who may drive the head over a network stream: a shared token, a rate limit per client, and one
controlling client at a time. Used by the UDP and TCP receivers (transports.py, tcp_server.py) through
:class:`StreamSource` (``guard=``); every refusal is counted in :class:`GuardStats`.

* **Token** (optional; required for a non-loopback bind): every UDP datagram carries ``"token": "..."``; a
  TCP connection sends it once, in its first line (``{"token": "..."}`` alone or with face data), and is
  closed if that line does not carry it. Compared in constant time. Without a token configured a ``token``
  key is ignored.
* **Rate limit**: a token bucket per client (UDP: source address and port; TCP: the connection), ``rate_hz``
  messages per second sustained with bursts of ``burst``; the excess is dropped before it is even parsed.
* **Control** (the takeover rule): the first client whose message is valid becomes the controller; messages
  from anyone else are dropped (``not_controlling``) while the controller keeps sending valid messages. Control
  passes to another client only when the controller has sent no valid message for ``takeover_s`` (default
  1 s: the stream is in dropout anyway) or its TCP connection closed. So a second local process cannot mix
  its frames into a live session, and a crashed sender is replaced within a second.
"""

from __future__ import annotations

import hmac
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable, MutableMapping
from dataclasses import dataclass
from typing import Any

from servoface.controller.inputs.errors import InputError

Client = Hashable
MAX_TRACKED_CLIENTS = 1024  # rate buckets kept (oldest forgotten first): a spoofed-port flood cannot grow memory


@dataclass
class GuardStats:
    unauthenticated: int = 0  # messages / connections without the right token
    rate_limited: int = 0  # messages over a client's rate, dropped unparsed
    not_controlling: int = 0  # valid messages from a client while another one has control
    control_changes: int = 0  # times control passed to a client (the first one included)
    connections: int = 0  # TCP connections accepted
    idle_closed: int = 0  # TCP connections closed for silence (idle timeout / no token in time)
    evicted: int = 0  # TCP connections closed to make room for a new one at the cap
    lines_too_long: int = 0

    def summary(self) -> dict[str, int]:
        return dict(self.__dict__)


class StreamGuard:
    """Token check, rate limits and the control rule (see the module doc). Thread-safe."""

    def __init__(
        self,
        token: str | None = None,
        *,
        rate_hz: float = 240.0,
        burst: float = 60.0,
        takeover_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if token is not None and (not isinstance(token, str) or len(token) < 8):
            raise InputError("token: expected a shared secret of at least 8 characters")
        for name, value in (("rate_hz", rate_hz), ("burst", burst), ("takeover_s", takeover_s)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value < 1e6:
                raise InputError(f"{name}: expected a positive number, got {value!r}")
        self._token = token.encode() if token is not None else None
        self.rate_hz = float(rate_hz)
        self.burst = float(max(1.0, burst))
        self.takeover_s = float(takeover_s)
        self.clock = clock
        self.stats = GuardStats()
        self._lock = threading.Lock()
        self._buckets: MutableMapping[Client, tuple[float, float]] = OrderedDict()
        self._controller: Client | None = None
        self._controller_seen_s = -1e18

    @property
    def needs_token(self) -> bool:
        return self._token is not None

    @property
    def controller(self) -> Client | None:
        return self._controller

    def rate_ok(self, client: Client) -> bool:
        """Take one message from ``client``'s bucket; False (counted) if it is empty."""
        return self.take(client, 1) == 1

    def take(self, client: Client, count: int) -> int:
        """Take ``count`` messages from ``client``'s bucket: how many fit (the rest are counted as limited)."""
        now = self.clock()
        with self._lock:
            buckets = self._buckets
            tokens, last = buckets.pop(client, (self.burst, now))
            tokens = min(self.burst, tokens + (now - last) * self.rate_hz)
            allowed = min(count, int(tokens))
            buckets[client] = (tokens - allowed, now)
            while len(buckets) > MAX_TRACKED_CLIENTS:
                buckets.pop(next(iter(buckets)))
            self.stats.rate_limited += count - allowed
            return allowed

    def token_ok(self, obj: Any) -> bool:
        """True if ``obj`` (a parsed message) carries the token, or none is configured. Counts failures."""
        if self._token is None:
            return True
        given = obj.get("token") if isinstance(obj, dict) else None
        ok = isinstance(given, str) and hmac.compare_digest(given.encode("utf-8", "replace"), self._token)
        if not ok:
            with self._lock:
                self.stats.unauthenticated += 1
        return ok

    def claim(self, client: Client) -> bool:
        """A valid message from ``client``: True if it has (or now takes) control, else counted and False."""
        now = self.clock()
        with self._lock:
            if self._controller == client:
                self._controller_seen_s = now
                return True
            if self._controller is None or now - self._controller_seen_s > self.takeover_s:
                self._controller, self._controller_seen_s = client, now
                self.stats.control_changes += 1
                return True
            self.stats.not_controlling += 1
            return False

    def release(self, client: Client) -> None:
        """``client`` is gone (its TCP connection closed): control is free at once."""
        with self._lock:
            if self._controller == client:
                self._controller = None
            self._buckets.pop(client, None)

    def count(self, field: str, n: int = 1) -> None:
        with self._lock:
            setattr(self.stats, field, getattr(self.stats, field) + n)
