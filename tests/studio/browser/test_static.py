"""The studio's front end is files the project wrote, shipped in the package: nothing is fetched from
elsewhere (it works offline) and every module a page imports is there. No browser needed."""

from __future__ import annotations

import re
from pathlib import Path

import servoface.controller.studio as studio_pkg

from tests.studio.browser.conftest import chromium_path

STATIC = Path(studio_pkg.__file__).resolve().parent / "static"
URL_RE = re.compile(r"""(?:https?:)?//[a-z0-9.-]+\.[a-z]{2,}""", re.IGNORECASE)
IMPORT_RE = re.compile(r"""(?:import\s[^'"]*from\s*|import\s*\(\s*|import\s+)["'](\.{1,2}/[^"']+)["']""")
SRC_RE = re.compile(r"""(?:src|href)="(/static/[^"]+)\"""")


def test_the_front_end_fetches_nothing_from_elsewhere() -> None:
    files = [p for p in STATIC.rglob("*") if p.is_file()]
    assert {p.suffix for p in files} <= {".html", ".css", ".js", ".svg"}
    for path in files:
        text = path.read_text(encoding="utf-8")
        found = [m for m in URL_RE.findall(text) if m != "http://www.w3.org"]  # the SVG namespace name
        assert not found, f"{path.relative_to(STATIC)} refers to {found}: the studio must work offline"


def test_every_module_and_file_a_page_loads_is_shipped() -> None:
    index = (STATIC / "index.html").read_text(encoding="utf-8")
    for ref in SRC_RE.findall(index):
        assert (STATIC / ref.removeprefix("/static/")).is_file(), ref
    for module in STATIC.rglob("*.js"):
        for ref in IMPORT_RE.findall(module.read_text(encoding="utf-8")):
            assert (module.parent / ref).resolve().is_file(), f"{module.name} imports {ref}"


def test_a_chromium_that_is_not_there_is_not_used(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("SERVOFACE_CHROMIUM", "/nonexistent/chromium")
    assert chromium_path() is None  # the browser tests then skip, saying how to install it
