"""The ASGI middleware in front of every route and WebSocket: token, Origin, rate and body size (see
API.md "Security"). A refusal never reaches a route: HTTP gets the JSON error body, a WebSocket handshake
is closed (the browser sees HTTP 403) before it is accepted."""

from __future__ import annotations

import json
from http.cookies import SimpleCookie
from typing import Any
from urllib.parse import parse_qsl

from servoface.controller.studio.errors import StudioError, TooLargeError
from servoface.controller.studio.security import (
    MAX_BODY_BYTES,
    OriginPolicy,
    RateLimiter,
    check_token,
)

Scope = dict[str, Any]


def _headers(scope: Scope) -> dict[str, str]:
    out: dict[str, str] = {}
    for key, value in scope.get("headers", []):
        out[key.decode("latin-1").lower()] = value.decode("latin-1")
    return out


def _query(scope: Scope) -> dict[str, str]:
    raw = scope.get("query_string", b"").decode("latin-1")
    try:
        return dict(parse_qsl(raw, keep_blank_values=True, max_num_fields=64))
    except ValueError:
        return {}


def _cookies(headers: dict[str, str]) -> dict[str, str]:
    jar: SimpleCookie = SimpleCookie()
    try:
        jar.load(headers.get("cookie", ""))
    except Exception:  # noqa: BLE001 - a malformed cookie header is no cookie
        return {}
    return {k: v.value for k, v in jar.items()}


class Gatekeeper:
    """Wraps the app: ``token``, ``origins``, ``limiter``, ``max_body`` bytes."""

    def __init__(
        self, app: Any, token: str, origins: OriginPolicy, limiter: RateLimiter, max_body: int = MAX_BODY_BYTES
    ) -> None:
        self.app = app
        self.token = token
        self.origins = origins
        self.limiter = limiter
        self.max_body = max_body

    async def __call__(self, scope: Scope, receive: Any, send: Any) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = _headers(scope)
        client = scope.get("client") or ("?", 0)
        try:
            self.limiter.take(str(client[0]))
            self.origins.check(headers.get("origin"))
            check_token(headers, _query(scope), _cookies(headers), self.token)
            if kind == "http":
                length = headers.get("content-length")
                if length is not None and (not length.isdigit() or int(length) > self.max_body):
                    raise TooLargeError(f"request body over {self.max_body} bytes", field="body")
        except StudioError as err:
            if kind == "websocket":
                await send({"type": "websocket.close", "code": 1008, "reason": err.code})
                return
            await _send_error(send, err)
            return
        if kind == "websocket":
            await self.app(scope, receive, send)
            return
        chunks: list[bytes] = []  # read the whole body first (at most max_body): a refusal is a clean 413
        seen = 0
        while True:
            message = await receive()
            if message.get("type") == "http.disconnect":
                return
            chunk = message.get("body", b"")
            seen += len(chunk)
            if seen > self.max_body:
                await _send_error(send, TooLargeError(f"request body over {self.max_body} bytes", field="body"))
                return
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        replayed = False

        async def replay() -> Any:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


async def _send_error(send: Any, err: StudioError) -> None:
    body = json.dumps(err.body()).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    if err.status == 429:
        headers.append((b"retry-after", b"1"))
    await send({"type": "http.response.start", "status": err.status, "headers": headers})
    await send({"type": "http.response.body", "body": body})
