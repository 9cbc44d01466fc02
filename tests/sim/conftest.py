"""Fixtures shared by the twin's rendering tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from servoface.sim.render import HeadRenderer, egl_missing_reason


@pytest.fixture(scope="module")
def renderer(request: pytest.FixtureRequest) -> Iterator[HeadRenderer]:
    """A headless renderer of the requesting module's ``W`` x ``H`` (skipped where EGL is missing)."""
    reason = egl_missing_reason()
    if reason is not None:
        pytest.skip(reason)
    r = HeadRenderer(request.module.W, request.module.H)
    yield r
    r.close()
