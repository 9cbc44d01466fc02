"""Own-head profiles for tests: the built-in human profile copied with head.toml keys replaced, and the one
whose AU table limits AU12 to 0.5 (a head that cannot show the library's full smile)."""

from __future__ import annotations

import shutil
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HUMAN = ROOT / "sim" / "heads" / "human"
NARROW_AU12 = "expected a finite intensity in [0.0, 0.5]"  # what such a head says of AU12 = 1.0


def human_copy(folder: Path, **keys: str) -> Path:
    """The built-in human profile copied to ``folder`` with top-level keys of head.toml replaced (or added
    after ``face_type``); values as TOML text (``name='"mine"'``)."""
    shutil.copytree(HUMAN, folder)
    toml = folder / "head.toml"
    lines = toml.read_text().splitlines()
    for key, value in keys.items():
        at = next((i for i, line in enumerate(lines) if line.startswith(f"{key} =")), None)
        if at is None:
            lines.insert(lines.index('face_type = "human"') + 1, f"{key} = {value}")
        else:
            lines[at] = f"{key} = {value}"
    toml.write_text("\n".join(lines) + "\n")
    return folder


def narrow_au_copy(folder: Path, name: str = "narrow_au") -> Path:
    """`human_copy` named ``name`` whose own AU table limits AU12 to 0..0.5."""
    human_copy(folder, name=f'"{name}"', au_table='"au.toml"')
    table = (ROOT / "sim" / "au" / "human.toml").read_text()
    (folder / "au.toml").write_text(table.replace("[AU12]\n", "[AU12]\nrange = [0.0, 0.5]\n", 1))
    return folder
