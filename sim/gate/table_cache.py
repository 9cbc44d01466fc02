"""A pair's lookup table on disk (the axial and clearance tables): one ``.npz`` read back when it exists,
else built and saved; a file that says "no table" (``present`` False) is kept too, so a pair without a table
is not rebuilt either. The file's name carries the pair's TSS key and the table kind's version, so a file
found is one for this build; one that cannot be read is an error naming it (delete it to rebuild)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from servoface.sim.gate.errors import TssCacheError
from servoface.sim.gate.tss_cache import atomic_savez

T = TypeVar("T")


def cached_table(
    path: Path | None,
    build: Callable[[], T | None],
    *,
    kind: str,
    load: Callable[[Mapping[str, Any]], T],
    fields: Callable[[T], dict[str, Any]],
) -> T | None:
    """The table from ``path`` or built and saved (``path`` None: build only). ``load`` makes the table of an
    open file's arrays (a KeyError or ValueError it raises is the file's fault), ``fields`` gives the arrays
    to save a table as; ``kind`` names the table in the error message."""
    if path is not None and path.exists():
        try:
            with np.load(path) as z:
                if not bool(z["present"]):
                    return None
                return load(z)
        except (OSError, KeyError, ValueError) as err:
            raise TssCacheError(f"{kind} cache file {path} is unreadable ({err}); delete it to rebuild") from err
    got = build()
    if path is None:
        return got
    if got is None:
        atomic_savez(path, present=False)
    else:
        atomic_savez(path, present=True, **fields(got))
    return got
