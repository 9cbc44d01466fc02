"""The installed package as a user meets it: one import root, shipped data by name, from any folder.

The slow test builds the wheel, installs it into a fresh venv in a temporary folder outside the repo and
runs the commands a new user runs first from an empty folder.
"""

from __future__ import annotations

import re
import subprocess
import tomllib
import zipfile
from pathlib import Path

import pytest

from tests.wheel_venv import run

ROOT = Path(__file__).resolve().parents[1]
OURS = ("controller", "sim", "hardware", "calibration")


# folders below the four that install as a package of their own (not as servoface.controller.testing)
MAPPED = {"servoface.testing": "controller/testing"}


def _package_folders() -> set[str]:
    """The package each folder with an __init__.py installs as: under the deepest package-dir entry that
    holds it (controller/testing/x -> servoface.testing.x, controller/cli -> servoface.controller.cli)."""
    dirs = sorted(
        [(Path(p), f"servoface.{p}") for p in OURS] + [(Path(d), pkg) for pkg, d in MAPPED.items()],
        key=lambda item: -len(item[0].parts),
    )
    found = set()
    for top in OURS:
        for init in (ROOT / top).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT)
            folder, package = next((d, pkg) for d, pkg in dirs if rel == d or d in rel.parents)
            found.add(".".join([package, *rel.relative_to(folder).parts]))
    return found


def _folder_of(package: str) -> Path:
    """The repo folder a listed package installs from (through the deepest package-dir entry above it)."""
    mapping = {**{f"servoface.{p}": p for p in OURS}, **MAPPED}
    head = max((pkg for pkg in mapping if package == pkg or package.startswith(pkg + ".")), key=len)
    return (
        ROOT / mapping[head] / Path(*package[len(head) :].lstrip(".").split("."))
        if package != head
        else ROOT / mapping[head]
    )


def _data_folders() -> set[str]:
    """Listed folders without an __init__.py: data the wheel ships (samples, scripts, meshes, shaders, the
    studio's static files), listed so that setuptools does not warn that they look importable."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    listed = set(data["tool"]["setuptools"]["packages"])
    return {pkg for pkg in listed if _folder_of(pkg).is_dir() and not (_folder_of(pkg) / "__init__.py").exists()}


def test_pyproject_lists_every_package_under_the_servoface_root() -> None:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    listed = set(data["tool"]["setuptools"]["packages"])
    missing = sorted(_package_folders() - listed)
    extra = sorted(listed - _package_folders() - _data_folders())
    assert not missing, f"add these to [tool.setuptools] packages in pyproject.toml: {missing}"
    assert not extra, f"pyproject.toml lists packages with no folder: {extra}"
    for folder in map(_folder_of, _data_folders()):  # a data folder holds files besides .py ones
        assert any(f.is_file() and f.suffix != ".py" for f in folder.iterdir()), f"{folder}: no data files"
    assert "servoface.controller.testing" not in listed
    assert data["tool"]["setuptools"]["package-dir"] == {**{f"servoface.{p}": p for p in OURS}, **MAPPED}


def _readme_api_example() -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split("## Python API in ten lines", 1)[1]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match is not None, "README has no Python block under 'Python API in ten lines'"
    return match.group(1)


_run = run


@pytest.fixture(scope="module")
def installed(wheel_venv: tuple[Path, Path, dict[str, str]]) -> tuple[Path, Path, dict[str, str]]:
    """(venv python, empty working folder, environment) with servoface's wheel installed, outside the repo
    (the session's one wheel venv, tests/conftest.py)."""
    python, base, env = wheel_venv
    work = base / "empty"
    work.mkdir(exist_ok=True)
    return python, work, dict(env)


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
    for shipped in (ROOT / "controller" / "studio" / "static").rglob("*"):  # the studio's front end, no CDN
        if shipped.is_file():
            assert f"servoface/{shipped.relative_to(ROOT)}" in names, shipped
    assert "servoface/controller/studio/API.md" in names
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
        ([servoface, "demo", "--out", "/proc/x"], 2),  # a folder that cannot be made: bad input
        ([servoface, "play", "no_such_script.toml", "--emulate"], 2),
        ([servoface, "play", "--input", "sample:nope", "--emulate"], 2),
        ([servoface, "play", "--input", "missing.csv", "--emulate"], 2),
        ([servoface, "play", "happiness", "--port", "/dev/does-not-exist"], 2),
    ]
    for cmd, code in cases:
        proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=120)
        assert proc.returncode == code, (cmd, proc.returncode, proc.stderr)
        assert "Traceback" not in proc.stderr and proc.stderr.strip(), (cmd, proc.stderr)
