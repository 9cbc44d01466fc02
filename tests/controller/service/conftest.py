"""A head service on the emulated human chain (in-process, SDK bytes on the emulated wire)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from servoface.controller.service import HeadService, OpenedHead, open_head


class Running:
    """An opened head and its service; ``chain`` is the emulator (assert on its state and packet log)."""

    def __init__(self, opened: OpenedHead, service: HeadService) -> None:
        self.opened = opened
        self.service = service
        self.chain: Any = opened.chain
        self.head = opened.head
        self.pipeline = opened.pipeline

    def close(self) -> None:
        try:
            self.service.shutdown(ease_s=0.0)
        finally:
            self.opened.chain.close()


def start_service(wire_time: bool = False, **kwargs: Any) -> Running:
    opened = open_head("human", emulate=True, wire_time=wire_time)
    return Running(opened, HeadService(opened.head, opened.pipeline, **kwargs))


@pytest.fixture
def running() -> Iterator[Running]:
    r = start_service()
    yield r
    r.close()
