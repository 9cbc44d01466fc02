"""What servoface ships, reachable by name from any folder: scripts, samples, heads, expression libraries.

A file that exists is always taken as given; otherwise a plain name (``human_performance``), a name with its
extension (``human_performance.toml``) or a prefixed one (``script:human_performance``,
``sample:openface_smile``) resolves to the copy inside the installed package. ``servoface list`` shows them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from servoface.controller.errors import ControllerError

PACKAGE_DIR = Path(__file__).resolve().parent
SCRIPTS_DIR = PACKAGE_DIR / "scripts"
SAMPLES_DIR = PACKAGE_DIR / "inputs" / "samples"
SAMPLE_SUFFIXES = (".csv", ".jsonl", ".fap")
SCRIPT_PREFIX = "script:"
SAMPLE_PREFIX = "sample:"

Kind = Literal["scripts", "samples", "heads", "expressions"]
KINDS: tuple[Kind, ...] = ("scripts", "samples", "heads", "expressions")


@dataclass(frozen=True)
class ShippedItem:
    """One thing the package ships: its name, what it is, and where it lies."""

    kind: Kind
    name: str
    path: Path
    note: str = ""


def shipped_scripts() -> dict[str, Path]:
    """Timeline scripts in ``controller/scripts/``, by name (file stem)."""
    return {p.stem: p for p in sorted(SCRIPTS_DIR.glob("*.toml"))}


def shipped_samples() -> dict[str, Path]:
    """Recorded tracker samples in ``controller/inputs/samples/``, by name (file stem)."""
    return {p.stem: p for p in sorted(SAMPLES_DIR.iterdir()) if p.suffix in SAMPLE_SUFFIXES}


def _strip(spec: str, prefix: str, suffixes: tuple[str, ...]) -> str:
    name = spec[len(prefix) :] if spec.startswith(prefix) else spec
    for suffix in suffixes:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def _is_file(path: Path) -> bool:
    """``path.is_file()``, False for a name the system cannot even look up (longer than it allows)."""
    try:
        return path.is_file()
    except OSError:
        return False


def is_shipped_script(spec: str | Path) -> bool:
    """True when ``spec`` is not an existing file but names a shipped script."""
    if isinstance(spec, Path) or _is_file(Path(spec)):
        return False
    return _strip(spec, SCRIPT_PREFIX, (".toml",)) in shipped_scripts()


def resolve_script(spec: str | Path) -> Path:
    """An existing file as given, else the shipped script ``spec`` names; ControllerError if neither."""
    path = Path(spec)
    if isinstance(spec, Path) or _is_file(path):
        return path
    scripts = shipped_scripts()
    name = _strip(spec, SCRIPT_PREFIX, (".toml",))
    if name in scripts and ("/" not in spec or spec.startswith(SCRIPT_PREFIX)):
        return scripts[name]
    if spec.startswith(SCRIPT_PREFIX):
        raise ControllerError(f"no shipped script {name!r}; shipped: {sorted(scripts)} (servoface list scripts)")
    return path  # a path that does not exist: the reader says so with its own message


def resolve_sample(spec: str | Path) -> Path:
    """An existing file as given, else the shipped sample ``spec`` names (``sample:NAME`` or NAME)."""
    path = Path(spec)
    if _is_file(path):
        return path
    text = str(spec)
    samples = shipped_samples()
    name = _strip(text, SAMPLE_PREFIX, SAMPLE_SUFFIXES)
    if name in samples and ("/" not in text or text.startswith(SAMPLE_PREFIX)):
        return samples[name]
    if text.startswith(SAMPLE_PREFIX):
        raise ControllerError(f"no shipped sample {name!r}; shipped: {sorted(samples)} (servoface list samples)")
    return path


def list_shipped(kind: Kind) -> list[ShippedItem]:
    """Everything of one kind the package ships, with its path."""
    if kind == "scripts":
        return [ShippedItem(kind, n, p, _title(p)) for n, p in shipped_scripts().items()]
    if kind == "samples":
        return [ShippedItem(kind, n, p, f"play with --input {SAMPLE_PREFIX}{n}") for n, p in shipped_samples().items()]
    from servoface.sim.heads import BUILTIN_HEADS, builtin_profile_dir

    if kind == "heads":
        return [ShippedItem(kind, n, builtin_profile_dir(n), "built-in profile") for n in BUILTIN_HEADS]
    if kind == "expressions":
        from servoface.sim.expressions import load_library
        from servoface.sim.expressions.library import EXPRESSIONS_DIR

        items = []
        for face_type in ("human", "dog"):
            path = EXPRESSIONS_DIR / f"{face_type}.toml"
            for name in sorted(load_library(face_type)):
                items.append(ShippedItem(kind, name, path, f"{face_type} library"))
        return items
    raise ControllerError(f"unknown kind {kind!r}; expected one of {list(KINDS)}")


def _title(path: Path) -> str:
    import tomllib

    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError):
        return ""
    script = data.get("script", {})
    title = script.get("title", "") if isinstance(script, dict) else ""
    face = script.get("face", "") if isinstance(script, dict) else ""
    return f"{face}: {title}" if face else str(title)
