"""A real browser for the studio's tests: Debian's Chromium driven by Playwright, launched from the system's
executable (never a browser Playwright downloads). Without Chromium the tests skip and say how to get it."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from typing import Any

import pytest

from tests.studio.conftest import StudioRig

CANDIDATES = ("chromium", "chromium-browser", "google-chrome")
TIMEOUT_MS = 60_000  # generous: a loaded 2-core CI machine; every wait is on a condition


def chromium_path() -> str | None:
    given = os.environ.get("SERVOFACE_CHROMIUM")
    if given:
        return given if os.access(given, os.X_OK) else None
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    path = chromium_path()
    if path is None:
        pytest.skip(
            "no Chromium on this machine: the browser tests need Debian's package "
            "(sudo apt-get install chromium; `make setup` installs it as root)"
        )
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("playwright is a dev dependency of servoface: pip install -e '.[dev]'")
    with sync_playwright() as pw:
        b = pw.chromium.launch(
            executable_path=path,
            args=["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"],
            timeout=TIMEOUT_MS,
        )
        yield b
        b.close()


def open_page(browser: Any, rig: StudioRig, hash_: str = "live", width: int = 1440, height: int = 900) -> Any:
    """The studio's page as a user opens it (the printed URL with the token), ready to use."""
    context = browser.new_context(viewport={"width": width, "height": height})
    context.set_default_timeout(TIMEOUT_MS)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda err: errors.append(str(err)))
    page.errors = errors
    page.goto(f"{rig.server.url}#{hash_}")
    page.wait_for_function("document.body.dataset.ready === '1'")
    page.wait_for_selector("#conn.ok")  # the WebSocket is open
    return page


@pytest.fixture
def studio_page(browser: Any, studio: StudioRig) -> Iterator[tuple[Any, StudioRig]]:
    page = open_page(browser, studio)
    yield page, studio
    assert not page.errors, f"the page raised: {page.errors}"
    page.context.close()
