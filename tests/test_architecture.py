"""The import rules of STYLE.md, enforced on the source tree (AST, no imports executed)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OURS = {"controller", "sim", "hardware", "calibration", "testing"}
# servoface.testing (the pytest plugin) lives in controller/testing/ but is a package of its own: it may use
# everything, and nothing of ours may import it (it is for tests, installed or not)
FOLDERS = {"testing": "controller/testing"}
ALLOWED: dict[str, set[str]] = {
    "hardware": set(),
    "calibration": set(),
    "sim": {"calibration"},
    "controller": {"sim", "hardware", "calibration"},
    "testing": {"controller", "sim", "hardware", "calibration"},
}


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
    return found


def _sources(package: str) -> list[Path]:
    """The modules of a package (a folder of ours, or a tests/examples folder); a folder mapped to a package
    of its own (controller/testing -> servoface.testing) belongs to that one, not to its parent folder."""
    top = ROOT / FOLDERS.get(package, package)
    inner = [ROOT / f for name, f in FOLDERS.items() if name != package and (ROOT / f).is_relative_to(top)]
    return sorted(p for p in top.rglob("*.py") if not any(p.is_relative_to(d) for d in inner))


def _ours(name: str) -> str | None:
    """The package of ours a module name imports (``servoface.sim.gate`` -> ``sim``), else None."""
    parts = name.split(".")
    if parts[0] == "servoface" and len(parts) > 1 and parts[1] in OURS:
        return parts[1]
    return None


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_packages_import_only_what_they_may(package: str) -> None:
    bad = []
    for path in _sources(package):
        for lineno, name in _imports(path):
            top = _ours(name)
            if top is not None and top != package and top not in ALLOWED[package]:
                bad.append(f"{path.relative_to(ROOT)}:{lineno} imports {name}")
    assert not bad, "forbidden imports:\n" + "\n".join(bad)


def test_the_rules_see_the_imports() -> None:
    """The rules above are not vacuous: controller does import the three others under the root, the test kit
    imports all four and is seen as its own package (its folder is not counted as controller's)."""
    seen = {_ours(name) for path in _sources("controller") for _, name in _imports(path)}
    assert {"sim", "hardware", "calibration", "controller"} <= seen
    kit = {_ours(name) for path in _sources("testing") for _, name in _imports(path)}
    assert {"sim", "hardware", "calibration", "controller", "testing"} <= kit
    assert not any(p.is_relative_to(ROOT / "controller" / "testing") for p in _sources("controller"))


def test_the_test_kit_is_imported_by_one_name_only() -> None:
    """controller/testing/ installs as servoface.testing; importing it as servoface.controller.testing
    (which an editable install would allow) would load a second copy of every module."""
    bad = [
        f"{path.relative_to(ROOT)}:{lineno} imports {name}"
        for folder in ("controller", "sim", "hardware", "calibration", "tests", "examples")
        for path in _sources(folder)
        for lineno, name in _imports(path)
        if name.startswith("servoface.controller.testing")
    ]
    assert not bad, "use servoface.testing:\n" + "\n".join(bad)


@pytest.mark.parametrize("folder", ["controller", "sim", "hardware", "calibration", "tests", "examples"])
def test_every_import_of_ours_goes_through_the_servoface_root(folder: str) -> None:
    """``import controller`` / ``from sim...`` would load a second copy of a module (or a user's own
    package of that name): everything of ours is imported as ``servoface.<package>``."""
    bad = [
        f"{path.relative_to(ROOT)}:{lineno} imports {name}"
        for path in _sources(folder)
        for lineno, name in _imports(path)
        if name.split(".")[0] in OURS
    ]
    assert not bad, "imports outside the servoface root:\n" + "\n".join(bad)


def test_only_the_dynamixel_bus_imports_the_sdk() -> None:
    users = [
        str(path.relative_to(ROOT))
        for package in OURS
        for path in _sources(package)
        if any(name.split(".")[0] == "dynamixel_sdk" for _, name in _imports(path))
    ]
    assert len(users) <= 1, f"only one module may import dynamixel_sdk, found {users}"
    assert all(u.startswith("hardware/") and "emulator" not in u for u in users), users


def test_emulator_is_independent_of_the_driver() -> None:
    bad = []
    for path in _sources("hardware/emulator"):
        for lineno, name in _imports(path):
            if _ours(name) is not None and not name.startswith("servoface.hardware.emulator"):
                bad.append(f"{path.relative_to(ROOT)}:{lineno} imports {name}")
            if name.split(".")[0] in {"dynamixel_sdk", "serial"} and "pty" not in path.name:
                bad.append(f"{path.relative_to(ROOT)}:{lineno} imports {name}")
    assert not bad, "the emulator must not import the driver side:\n" + "\n".join(bad)


def test_print_only_in_the_cli() -> None:
    bad = []
    for package in OURS:
        for path in _sources(package):
            if path.is_relative_to(ROOT / "controller" / "cli"):
                continue
            tree = ast.parse(path.read_text(encoding="utf-8"))
            for node in ast.walk(tree):
                if (
                    isinstance(node, ast.Call)
                    and isinstance(node.func, ast.Name)
                    and node.func.id
                    in {
                        "print",
                        "input",
                    }
                ):
                    bad.append(f"{path.relative_to(ROOT)}:{node.lineno} calls {node.func.id}")
    assert not bad, "print/input belong in controller/cli only:\n" + "\n".join(bad)
