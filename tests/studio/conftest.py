"""Fixtures of the studio's tests: a real studio (uvicorn on an ephemeral loopback port) around a head
service on the in-process emulator, reached with real HTTP and WebSocket clients. Assertions about motion
read the emulator (the far end of the wire), never the studio's own state."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from servoface.controller.service import HeadService, open_head
from servoface.controller.studio import StudioOptions, StudioServer
from servoface.controller.studio.security import RateLimiter


@dataclass
class StudioRig:
    server: StudioServer
    service: HeadService
    chain: Any
    client: Any  # httpx.Client with the token

    @property
    def base_url(self) -> str:
        return self.server.base_url

    @property
    def token(self) -> str:
        return self.server.token

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.server.port}/api/ws?token={self.token}"

    def goal_tick(self, servo_id: int) -> int:
        return int(self.chain.servo(servo_id).read_register("Goal Position"))

    def goals(self) -> dict[int, int]:
        return {sid: self.goal_tick(sid) for sid in self.chain.ids}

    def torque(self, servo_id: int) -> int:
        return int(self.chain.servo(servo_id).read_register("Torque Enable"))

    def limits(self) -> dict[int, tuple[int, int]]:
        return dict(self.service.pipeline.calibration.position_limits_tick())

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float = 20.0, what: str = "condition") -> None:
        """Generous waits on a condition (never on wall time as a claim)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return
            time.sleep(0.02)
        raise AssertionError(f"timed out waiting for {what}")

    @contextmanager
    def connect(self, **kw: Any) -> Iterator[Any]:
        """A WebSocket to the studio, past its hello (``with rig.connect() as ws``)."""
        from websockets.sync.client import connect

        # max_queue=None: the client keeps reading (and answering pings) while a test is not looking
        with connect(self.ws_url, open_timeout=20, max_queue=None, **kw) as ws:
            hello = json.loads(ws.recv(timeout=20))
            assert hello["type"] == "hello"
            yield ws


def _open(tmp_path: Path, *, render: bool, head: str = "human", rate: float | None = None) -> StudioRig:
    import httpx

    opened = open_head(head, emulate=True, wire_time=False)  # no byte timing: deterministic on a loaded box
    service = HeadService(opened.head, opened.pipeline)
    options = StudioOptions(out_dir=tmp_path, scripts_dir=tmp_path, render=render)
    limiter = RateLimiter(rate_per_s=rate, burst=rate) if rate is not None else RateLimiter(1e6, 1e6)
    server = StudioServer(service, port=0, options=options, limiter=limiter).start()
    client = httpx.Client(base_url=server.base_url, headers={"Authorization": f"Bearer {server.token}"}, timeout=60)
    return StudioRig(server, service, opened.chain, client)


def _close(rig: StudioRig) -> None:
    rig.client.close()
    rig.server.stop()
    rig.service.shutdown(ease_s=0.0)
    rig.chain.close()


@pytest.fixture
def studio(tmp_path: Path) -> Iterator[StudioRig]:
    """A studio on the emulated human head, no renders (fast), rate limit off."""
    rig = _open(tmp_path, render=False)
    yield rig
    _close(rig)


@pytest.fixture(scope="module")
def studio_shared(tmp_path_factory: pytest.TempPathFactory) -> Iterator[StudioRig]:
    """One studio for a module's tests that leave no state behind (refusals, reads)."""
    rig = _open(tmp_path_factory.mktemp("studio"), render=False)
    yield rig
    _close(rig)


@pytest.fixture
def studio_render(tmp_path: Path) -> Iterator[StudioRig]:
    """A studio with the twin rendering (EGL on the CPU)."""
    rig = _open(tmp_path, render=True)
    yield rig
    _close(rig)


@pytest.fixture
def make_studio(tmp_path: Path) -> Iterator[Callable[..., StudioRig]]:
    rigs: list[StudioRig] = []

    def make(**kw: Any) -> StudioRig:
        rig = _open(tmp_path, **{"render": False, **kw})
        rigs.append(rig)
        return rig

    yield make
    for rig in rigs:
        _close(rig)
