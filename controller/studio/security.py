"""The studio's gatekeeping: the per-run token (compared in constant time), the Origin check, the body
size limit and a per-client token-bucket rate limit. Pure functions and small classes; the ASGI wiring is
in :mod:`.app`."""

from __future__ import annotations

import hmac
import ipaddress
import secrets
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from urllib.parse import urlsplit

from servoface.controller.studio.errors import ForbiddenOriginError, RateLimitedError, UnauthorizedError

TOKEN_COOKIE = "servoface_token"
MAX_BODY_BYTES = 1 << 20  # 1 MiB
MAX_WS_MESSAGE_BYTES = 64 << 10  # 64 KiB
RATE_PER_S = 100.0
RATE_BURST = 200.0
_LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1", "[::1]")


def new_token() -> str:
    """32 url-safe characters (192 bits), new each run."""
    return secrets.token_urlsafe(24)


def token_matches(given: str | None, expected: str) -> bool:
    """Constant-time comparison (``hmac.compare_digest`` on bytes); None or empty never matches."""
    if not given or not isinstance(given, str):
        return False
    return hmac.compare_digest(given.encode("utf-8", "surrogatepass"), expected.encode("utf-8"))


def token_from(headers: Mapping[str, str], query: Mapping[str, str], cookies: Mapping[str, str]) -> str | None:
    """The token a request carries: ``Authorization: Bearer``, ``X-Servoface-Token``, ``?token=`` or the
    cookie, in that order."""
    auth = headers.get("authorization", "")
    if auth[:7].lower() == "bearer ":
        return auth[7:].strip()
    for value in (headers.get("x-servoface-token"), query.get("token"), cookies.get(TOKEN_COOKIE)):
        if value:
            return value
    return None


def check_token(
    headers: Mapping[str, str], query: Mapping[str, str], cookies: Mapping[str, str], expected: str
) -> None:
    if not token_matches(token_from(headers, query, cookies), expected):
        raise UnauthorizedError("a valid studio token is required (the URL printed by `servoface studio`)")


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and 'localhost'."""
    name = host.strip("[]")
    if name == "localhost":
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


@dataclass(frozen=True)
class OriginPolicy:
    """The origins allowed to talk to the studio: its own (``http://HOST:PORT``), where any loopback name
    stands for any other, plus ``extra`` ones (``--allow-origin``)."""

    host: str
    port: int
    extra: frozenset[str] = frozenset()

    def allows(self, origin: str | None) -> bool:
        if origin is None:
            return True  # not a browser (curl, tests); the token still applies
        if origin in self.extra:
            return True
        try:
            parts = urlsplit(origin)
            port = parts.port or (443 if parts.scheme == "https" else 80)
        except ValueError:
            return False
        if parts.scheme not in ("http", "https") or port != self.port or parts.hostname is None:
            return False
        if is_loopback(self.host) or self.host in ("0.0.0.0", "::"):
            return is_loopback(parts.hostname) or parts.hostname == self.host
        return parts.hostname == self.host.strip("[]")

    def check(self, origin: str | None) -> None:
        if not self.allows(origin):
            raise ForbiddenOriginError(
                f"origin {origin!r} may not use this studio (only http://{self.host}:{self.port})"
            )


@dataclass
class _Bucket:
    tokens: float
    stamp_s: float


@dataclass
class RateLimiter:
    """A token bucket per client key (its address): ``rate_per_s`` sustained, ``burst`` at once."""

    rate_per_s: float = RATE_PER_S
    burst: float = RATE_BURST
    clock: Callable[[], float] = time.monotonic
    max_clients: int = 4096
    _buckets: dict[str, _Bucket] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def take(self, key: str, cost: float = 1.0) -> None:
        """Spend ``cost`` from ``key``'s bucket, or raise RateLimitedError (with the wait in the message)."""
        now = self.clock()
        with self._lock:
            bucket = self._buckets.get(key)
            if bucket is None:
                if len(self._buckets) >= self.max_clients:
                    self._buckets.clear()  # a flood of addresses: start over rather than grow
                bucket = self._buckets[key] = _Bucket(self.burst, now)
            bucket.tokens = min(self.burst, bucket.tokens + (now - bucket.stamp_s) * self.rate_per_s)
            bucket.stamp_s = now
            if bucket.tokens < cost:
                wait_s = (cost - bucket.tokens) / self.rate_per_s
                raise RateLimitedError(
                    f"too many requests from {key}: at most {self.rate_per_s:g}/s; retry in {wait_s:.2f} s"
                )
            bucket.tokens -= cost
