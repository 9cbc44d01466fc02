"""The installed package as a user meets it: one import root, shipped data by name, from any folder.

The slow test builds the wheel, installs it into a fresh venv in a temporary folder outside the repo and
runs the commands a new user runs first from an empty folder.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OURS = ("controller", "sim", "hardware", "calibration")


def _package_folders() -> set[str]:
    return {
        "servoface." + ".".join(p.parent.relative_to(ROOT).parts)
        for top in OURS
        for p in (ROOT / top).rglob("__init__.py")
    }


def test_pyproject_lists_every_package_under_the_servoface_root() -> None:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    listed = set(data["tool"]["setuptools"]["packages"])
    missing = sorted(_package_folders() - listed)
    extra = sorted(listed - _package_folders())
    assert not missing, f"add these to [tool.setuptools] packages in pyproject.toml: {missing}"
    assert not extra, f"pyproject.toml lists packages with no folder: {extra}"
    assert data["tool"]["setuptools"]["package-dir"] == {f"servoface.{p}": p for p in OURS}


def _readme_api_example() -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split("## Python API in ten lines", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match is not None, "README has no Python block under 'Python API in ten lines'"
    return match.group(1)


def _copy_source(dest: Path) -> Path:
    ignore = shutil.ignore_patterns(".venv", ".git", "out", "build", "*.egg-info", "__pycache__", ".ruff_cache")
    shutil.copytree(ROOT, dest, ignore=ignore)
    return dest


def _run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 300) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, (
        f"{' '.join(cmd)} exited {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    )
    return proc


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, str]]:
    """(venv python, empty working folder, environment) with servoface's wheel installed, outside the repo."""
    base = tmp_path_factory.mktemp("wheel")
    src = _copy_source(base / "src")
    wheel_dir = base / "dist"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheel_dir), str(src)], base, env)
    wheels = list(wheel_dir.glob("servoface-*.whl"))
    assert len(wheels) == 1, wheels
    venv = base / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], base, env)
    python = venv / "bin" / "python"
    _run(
        [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", str(wheels[0])],
        base,
        env,
        900,
    )
    work = base / "empty"
    work.mkdir()
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    return python, work, env


@pytest.mark.slow
def test_wheel_has_one_import_root_and_every_shipped_file(
    installed: tuple[Path, Path, dict[str, str]],
) -> None:
    python, work, env = installed
    wheel = next((work.parent / "dist").glob("servoface-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"servoface"}, f"top-level entries of the wheel: {sorted(tops)}"
    for sample in (ROOT / "controller" / "inputs" / "samples").iterdir():
        if sample.suffix in (".csv", ".jsonl", ".fap"):
            assert f"servoface/controller/inputs/samples/{sample.name}" in names, sample.name
    for script in (ROOT / "controller" / "scripts").glob("*.toml"):
        assert f"servoface/controller/scripts/{script.name}" in names
    assert any(n.startswith("servoface/sim/heads/human/") for n in names)
    for top in OURS:
        proc = subprocess.run([str(python), "-c", f"import {top}"], cwd=work, env=env, capture_output=True, text=True)
        assert proc.returncode != 0 and "No module named" in proc.stderr, f"`import {top}` worked in the fresh venv"


@pytest.mark.slow
def test_a_users_own_calibration_package_does_not_shadow_ours(
    installed: tuple[Path, Path, dict[str, str]],
) -> None:
    python, work, env = installed
    project = work / "shadow"
    (project / "calibration").mkdir(parents=True)
    (project / "calibration" / "__init__.py").write_text("MINE = True\n")
    (project / "controller.py").write_text("MINE = True\n")
    (project / "main.py").write_text(
        "import calibration, controller\n"
        "from servoface.calibration import HeadCalibration, load_calibration\n"
        "from servoface.controller.face import Face\n"
        "assert calibration.MINE and controller.MINE\n"
        "print('ok', HeadCalibration.__module__, Face.__module__)\n"
    )
    proc = _run([str(python), "main.py"], project, env)
    assert "ok servoface.calibration" in proc.stdout


@pytest.mark.slow
def test_first_commands_from_an_empty_folder(installed: tuple[Path, Path, dict[str, str]]) -> None:
    python, work, env = installed
    servoface = str(python.parent / "servoface")
    listing = _run([servoface, "list"], work, env).stdout
    assert "human_performance" in listing and "openface_smile" in listing and "happiness" in listing
    _run([servoface, "play", "human_performance", "--emulate", "--duration", "1.5"], work, env)
    samples = [
        p.stem for p in (ROOT / "controller" / "inputs" / "samples").iterdir() if p.suffix in (".csv", ".jsonl", ".fap")
    ]
    assert len(samples) >= 5
    for name in samples:
        out = _run([servoface, "play", "--input", f"sample:{name}", "--emulate", "--duration", "1.0"], work, env)
        assert "frames" in out.stdout, (name, out.stdout)
    (work / "api_example.py").write_text(_readme_api_example())
    out = _run([str(python), "api_example.py"], work, env, 300)
    assert "accept" in out.stdout
    demo = _run([servoface, "demo", "--out", "x"], work, env, 600)
    assert (work / "x" / "report.json").is_file() and (work / "x" / "sheet.png").is_file(), demo.stdout
    assert list(work.iterdir()) and not (work / "controller").exists()


@pytest.mark.slow
def test_bad_paths_get_a_message_not_a_traceback(installed: tuple[Path, Path, dict[str, str]]) -> None:
    python, work, env = installed
    servoface = str(python.parent / "servoface")
    cases = [
        ([servoface, "preview", "happiness", "-o", "/proc/x.png"], 2),
        ([servoface, "demo", "--out", "/proc/x"], 1),
        ([servoface, "play", "no_such_script.toml", "--emulate"], 2),
        ([servoface, "play", "--input", "sample:nope", "--emulate"], 2),
        ([servoface, "play", "--input", "missing.csv", "--emulate"], 2),
        ([servoface, "play", "happiness", "--port", "/dev/does-not-exist"], 2),
    ]
    for cmd, code in cases:
        proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=120)
        assert proc.returncode == code, (cmd, proc.returncode, proc.stderr)
        assert "Traceback" not in proc.stderr and proc.stderr.strip(), (cmd, proc.stderr)
