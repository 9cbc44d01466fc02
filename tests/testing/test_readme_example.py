"""The README's example test file, run as another project would run it (a temporary folder, no conftest)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from tests.testing.junit import outcomes

ROOT = Path(__file__).resolve().parents[2]


def _example() -> str:
    section = (ROOT / "README.md").read_text().split("## Test your own code against the emulator", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match is not None, "README has no Python block under 'Test your own code against the emulator'"
    return match.group(1)


def test_the_readme_example_passes(tmp_path: Path) -> None:
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_my_head.py").write_text(_example())
    env = {k: v for k, v in os.environ.items() if not k.startswith("SERVOFACE_")}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rs", "--junitxml=report.xml", "tests"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    got = outcomes(tmp_path / "report.xml")
    assert len(got) == 4 and all(outcome == "passed" for outcome, _ in got.values()), (got, proc.stdout[-3000:])
