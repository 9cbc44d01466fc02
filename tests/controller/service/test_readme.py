"""The README's head-service example runs as written (on the emulator)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def test_the_readme_service_example_runs() -> None:
    section = (ROOT / "README.md").read_text().split("## The head service", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match is not None, "README has no Python block under 'The head service'"
    scope: dict[str, object] = {}
    exec(compile(match.group(1), "README.md", "exec"), scope)  # noqa: S102 - our own documentation
    svc = scope["svc"]
    opened = scope["opened"]
    try:
        assert svc.report is not None and svc.report.torque_off  # type: ignore[attr-defined]
        assert str(scope["cue"].status) in ("done", "cancelled")  # type: ignore[attr-defined]
        assert all(not opened.chain.servo(s).torque_on for s in opened.chain.ids)  # type: ignore[attr-defined]
    finally:
        opened.chain.close()  # type: ignore[attr-defined]
