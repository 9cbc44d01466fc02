"""Head profiles: the built-in ``human`` and ``dog`` heads and user profile folders.

``load_head("human")``, ``load_head("dog")`` or ``load_head("/path/to/my_head")`` (a folder with a
``head.toml``; start by copying ``sim/heads/human`` or ``sim/heads/dog``).
"""

from __future__ import annotations

import difflib
from pathlib import Path

from servoface.sim.errors import HeadProfileError
from servoface.sim.head import Head

BUILTIN_DIR = Path(__file__).resolve().parent
BUILTIN_HEADS = ("human", "dog")

_CACHE: dict[tuple[str, tuple[tuple[str, float], ...]], Head] = {}


def _stamp(file: Path) -> tuple[tuple[str, float], ...]:
    """Modification times of the profile and of the files beside it and one folder down (meshes)."""
    near: list[Path] = []
    for p in sorted(file.parent.iterdir())[:200]:
        if p.is_dir():
            near += [q for q in sorted(p.iterdir())[:200] if q.is_file()]
        elif p != file:
            near.append(p)
    return tuple((str(p), p.stat().st_mtime) for p in [file, *near[:400]])


def builtin_profile_dir(name: str) -> Path:
    """The folder of a built-in profile (copy it to start your own)."""
    if name not in BUILTIN_HEADS:
        raise HeadProfileError(f"no built-in head {name!r}; built-ins: {list(BUILTIN_HEADS)}")
    return BUILTIN_DIR / name


def load_head(name_or_path: str | Path) -> Head:
    """Load a head: a built-in name ("human", "dog") or a profile folder / head.toml path.

    Results are cached per file and modification time; the returned Head and its arrays are read-only
    by contract (skin arrays are flagged non-writeable).
    """
    from servoface.sim.profile import load_profile

    if isinstance(name_or_path, str) and name_or_path in BUILTIN_HEADS:
        path = builtin_profile_dir(name_or_path)
    else:
        path = Path(name_or_path)
        if not path.exists():
            near = difflib.get_close_matches(str(name_or_path), list(BUILTIN_HEADS), n=1, cutoff=0.6)
            hint = f" (did you mean {near[0]!r}?)" if near and "/" not in str(name_or_path) else ""
            raise HeadProfileError(
                f"{path}: expected a built-in head name {list(BUILTIN_HEADS)} or a profile folder with head.toml" + hint
            )
    file = path / "head.toml" if path.is_dir() else path
    try:
        key = (str(file.resolve()), _stamp(file))
    except OSError as err:
        raise HeadProfileError(f"{file}: expected a head profile file (head.toml): {err.strerror or err}") from err
    head = _CACHE.get(key)
    if head is None:
        head = load_profile(path)
        _CACHE[key] = head
    return head


__all__ = ["BUILTIN_HEADS", "Head", "builtin_profile_dir", "load_head"]
