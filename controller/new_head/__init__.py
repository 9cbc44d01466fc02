"""`servoface new DIR --from human|dog|mechanical`: write a commented head profile to edit.

- ``human`` / ``dog``: a copy of the built-in profile (its procedural meshes stay ``builtin:``), plus a
  ``direct.toml`` derived from its muscle model (switched off: uncomment ``au_direct`` to use it);
- ``mechanical``: an 8-servo head of rigid parts and no skin (meshes written as STL into ``meshes/``)
  with a direct table for its brows.

Every kind also gets ``calibration_template.csv``: ``role,target,tick`` rows at the lower limit, neutral,
upper limit and three points between, with the ticks of an ideal servo (2048 = neutral). Replace the ticks
by what you measure on your head and run ``servoface calibrate --head DIR --csv DIR/calibration_template.csv``
(``servoface calibrate --head DIR --template`` writes it again for a head.toml edited since: see ``template``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from servoface.controller.errors import ControllerError
from servoface.controller.new_head.template import TEMPLATE_CSV, write_template_csv

KINDS = ("human", "dog", "mechanical")


@dataclass(frozen=True)
class NewHead:
    folder: Path
    files: tuple[Path, ...]
    kind: str


def _name_for(folder: Path) -> str:
    name = re.sub(r"[^A-Za-z0-9_-]+", "_", folder.resolve().name).strip("_")
    return name or "my_head"


def _copy_builtin(folder: Path, kind: str, name: str) -> str:
    from servoface.sim.heads import builtin_profile_dir

    text = (builtin_profile_dir(kind) / "head.toml").read_text(encoding="utf-8")
    text = re.sub(r'(?m)^name = "[^"]*"', f'name = "{name}"', text, count=1)
    text = re.sub(r'(?m)^calibration = "[^"]*"', 'calibration = "calibration.json"', text, count=1)
    header = (
        f"# servoface head profile `{name}`, written by `servoface new --from {kind}` from the built-in {kind} head.\n"
        "# Edit it to match your head: servo ids and models (`servoface scan` lists them), joint pivots/axes/limits,\n"
        '# anchor points and lines, ranges. Replace "builtin:..." meshes by your STL/OBJ/GLB files (mm; for a\n'
        "# mesh in metres set scale = 1000). Remove what your head lacks: every section is optional, the AU\n"
        "# table is applied to what the head has and `servoface check` lists what it then cannot show.\n"
        "# To drive servos straight from AUs instead of the muscle model, uncomment:\n"
        '# au_direct = "direct.toml"\n'
        f"# Next: `servoface calibrate --head {folder} --csv {folder / TEMPLATE_CSV}` (put your measured\n"
        f"# ticks in it first), or on the head: `servoface calibrate --head {folder} --port /dev/ttyUSB0`.\n"
    )
    return header + text


def _files_written(folder: Path, kind: str) -> list[Path]:
    """Every file `write_new_head` writes for ``kind`` into ``folder`` (but head.toml, checked first)."""
    out = [folder / "direct.toml", folder / TEMPLATE_CSV]
    if kind == "mechanical":
        from servoface.controller.new_head.mechanical import meshes

        out += [folder / "meshes" / f"{name}.stl" for name in meshes()]
    return out


def write_new_head(folder: Path, kind: str, *, force: bool = False) -> NewHead:
    """Write a new profile of ``kind`` into ``folder`` (created; an existing head.toml needs ``force``)."""
    from servoface.sim.au.direct import derive_direct_table
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head

    if kind not in KINDS:
        raise ControllerError(f"--from: expected one of {list(KINDS)}, got {kind!r}")
    if not str(folder).strip():
        raise ControllerError("folder: expected the name of the profile folder to create, got ''")
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ControllerError(f"{folder}: exists and is not a folder")
    if (folder / "head.toml").exists() and not force:
        raise ControllerError(f"{folder / 'head.toml'} exists already; pick another folder or pass --force")
    mine = [p for p in _files_written(folder, kind) if p.exists()]
    if mine and not force:  # e.g. the builder's own meshes/jaw.stl or measured calibration_template.csv
        shown = ", ".join(str(p) for p in mine[:3]) + (f" and {len(mine) - 3} more" if len(mine) > 3 else "")
        raise ControllerError(f"{folder}: would overwrite {shown}, already there; pick another folder or pass --force")
    folder.mkdir(parents=True, exist_ok=True)
    name = _name_for(folder)
    files: list[Path] = []
    if kind == "mechanical":
        from servoface.controller.new_head import mechanical

        files += mechanical.write_meshes(folder / "meshes")
        (folder / "head.toml").write_text(mechanical.HEAD_TOML.format(folder=folder, name=name), encoding="utf-8")
        (folder / "direct.toml").write_text(mechanical.DIRECT_TOML, encoding="utf-8")
    else:
        (folder / "head.toml").write_text(_copy_builtin(folder, kind, name), encoding="utf-8")
        model = FaceModel(load_head(folder))
        note = f"switched off: uncomment au_direct in head.toml to use it (from the built-in {kind} muscle model)"
        (folder / "direct.toml").write_text(derive_direct_table(model, note=note), encoding="utf-8")
    files += [folder / "head.toml", folder / "direct.toml", write_template_csv(folder)]
    return NewHead(folder, tuple(files), kind)


__all__ = ["KINDS", "TEMPLATE_CSV", "NewHead", "write_new_head", "write_template_csv"]
