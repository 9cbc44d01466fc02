"""servoface's wheel installed into a fresh venv outside the repo: built once per test session and shared
by the tests that need it (tests/test_packaging.py, tests/testing/test_user_project.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def copy_source(dest: Path) -> Path:
    ignore = shutil.ignore_patterns(".venv", ".git", "out", "build", "*.egg-info", "__pycache__", ".ruff_cache")
    shutil.copytree(ROOT, dest, ignore=ignore)
    return dest


def run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 300) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, (
        f"{' '.join(cmd)} exited {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    )
    return proc


def build(base: Path) -> tuple[Path, dict[str, str]]:
    """(venv python, environment) with servoface's wheel (in ``base/dist``) installed in ``base/venv``."""
    src = copy_source(base / "src")
    wheel_dir = base / "dist"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheel_dir), str(src)], base, env)
    wheels = list(wheel_dir.glob("servoface-*.whl"))
    assert len(wheels) == 1, wheels
    venv = base / "venv"
    run([sys.executable, "-m", "venv", str(venv)], base, env)
    python = venv / "bin" / "python"
    run([str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", str(wheels[0])], base, env, 900)
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    return python, env
