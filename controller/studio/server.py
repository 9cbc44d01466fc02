"""Serving the studio: uvicorn on a thread of its own (loopback by default; beyond it only with
``allow_remote``), the :class:`Studio` and its observer pump around a running :class:`HeadService`.
``StudioServer(...).start()`` returns once the socket listens; ``url`` carries the per-run token."""

from __future__ import annotations

import threading
import time
from typing import Any

from servoface.controller.service import HeadService
from servoface.controller.studio.errors import StudioError
from servoface.controller.studio.security import (
    MAX_WS_MESSAGE_BYTES,
    OriginPolicy,
    RateLimiter,
    is_loopback,
    new_token,
)
from servoface.controller.studio.studio import Studio, StudioOptions

WS_PING_INTERVAL_S = 1.0  # the server pings every second ...
WS_PING_TIMEOUT_S = 3.0  # ... and a browser silent for 3 s more is gone (tolerant of a loaded machine)


class StudioServer:
    def __init__(
        self,
        service: HeadService,
        *,
        host: str = "127.0.0.1",
        port: int = 8765,
        allow_remote: bool = False,
        options: StudioOptions | None = None,
        token: str | None = None,
        limiter: RateLimiter | None = None,
        allow_origins: frozenset[str] = frozenset(),
    ) -> None:
        if not is_loopback(host) and not allow_remote:
            raise StudioError(
                f"--host {host}: the studio binds loopback only unless --allow-remote is given "
                "(the token still applies; anyone on that network can reach the port)"
            )
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise StudioError(f"--port-http: expected 0..65535, got {port!r}")
        self.service = service
        self.host = host
        self.port = port
        self.token = token or new_token()
        self.limiter = limiter or RateLimiter()
        self.allow_origins = allow_origins
        self.studio = Studio(service, options)
        self.pump: Any = None
        self._server: Any = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/?token={self.token}"

    @property
    def base_url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"

    def start(self, timeout_s: float = 30.0) -> StudioServer:
        import socket

        import uvicorn
        from servoface.controller.studio.app import create_app
        from servoface.controller.studio.pump import Pump

        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((self.host, self.port))
        self.port = int(sock.getsockname()[1])
        origins = OriginPolicy(self.host, self.port, self.allow_origins)
        app = create_app(self.studio, self.token, origins, self.limiter)
        config = uvicorn.Config(
            app,
            log_level="warning",
            lifespan="off",
            ws_max_size=MAX_WS_MESSAGE_BYTES,
            ws_ping_interval=WS_PING_INTERVAL_S,
            ws_ping_timeout=WS_PING_TIMEOUT_S,
            access_log=False,
            server_header=False,
        )
        self._server = uvicorn.Server(config)
        self.pump = Pump(self.studio)
        self._thread = threading.Thread(
            target=self._server.run, kwargs={"sockets": [sock]}, name="studio-http", daemon=True
        )
        self._thread.start()
        deadline = time.monotonic() + timeout_s
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise StudioError(f"the studio's web server did not start on {self.host}:{self.port}")
            time.sleep(0.02)
        return self

    @property
    def running(self) -> bool:
        """The server's thread is serving (False once it ended, by `stop` or on its own)."""
        return self._thread is not None and self._thread.is_alive()

    def wait(self) -> None:
        """Block until the server stops (Ctrl-C in the main thread raises KeyboardInterrupt here)."""
        while self._thread is not None and self._thread.is_alive():
            self._thread.join(0.2)

    def stop(self) -> None:
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(10.0)
        if self.pump is not None:
            self.pump.close()
        self.studio.close()
