"""TSS tables on disk: one ``.npz`` per part pair, written atomically, read back only when its key matches."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from servoface.sim.gate.errors import TssCacheError
from servoface.sim.gate.spheres import SphereSet
from servoface.sim.gate.tss_build import PairTable


def atomic_savez(path: Path, compressed: bool = False, **arrays: Any) -> None:
    """``np.savez`` (or ``savez_compressed``) to a temporary file beside ``path``, then renamed into place:
    a reader never sees a half-written file, and two builds writing the same file do not mix."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + f".{os.getpid()}.tmp.npz")
        (np.savez_compressed if compressed else np.savez)(tmp, **arrays)
        os.replace(tmp, path)
    except OSError as err:
        raise TssCacheError(f"cannot write cache file {path}: {err}") from err


def save_table(path: Path, table: PairTable, sa: SphereSet, sb: SphereSet) -> None:
    atomic_savez(
        path,
        compressed=True,
        a=table.a,
        b=table.b,
        joints=np.array(table.joints, dtype=str),
        lower=table.lower_deg,
        upper=table.upper_deg,
        ia=table.ia,
        ib=table.ib,
        n_all=table.n_all_pairs,
        margin=table.margin_mm,
        step=table.step_deg,
        grid=table.grid_points,
        tol=table.tolerance_mm,
        key=table.key,
        exact_only=table.exact_only,
        ca=sa.centres_mm,
        ra=sa.radii_mm,
        cb=sb.centres_mm,
        rb=sb.radii_mm,
    )


def load_table(path: Path, key: str) -> tuple[PairTable, SphereSet, SphereSet] | None:
    if not path.exists():
        return None
    try:
        with np.load(path) as z:
            if str(z["key"]) != key:
                return None
            table = PairTable(
                str(z["a"]),
                str(z["b"]),
                tuple(str(s) for s in z["joints"]),
                z["lower"],
                z["upper"],
                z["ia"].astype(np.int64),
                z["ib"].astype(np.int64),
                int(z["n_all"]),
                float(z["margin"]),
                z["step"],
                int(z["grid"]),
                float(z["tol"]),
                key,
                bool(z["exact_only"]),
            )
            return table, SphereSet(z["ca"], z["ra"]), SphereSet(z["cb"], z["rb"])
    except (OSError, KeyError, ValueError) as err:
        raise TssCacheError(f"TSS cache file {path} is unreadable ({err}); delete it to rebuild") from err
