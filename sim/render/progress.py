"""A progress bar for long renders: tqdm on stderr, silent when asked or when stderr is not a terminal."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")


def progress(
    items: Iterable[T], total: int | None = None, desc: str = "rendering", enabled: bool | None = None
) -> Iterator[T]:
    """Iterate ``items`` with a tqdm bar on stderr. ``enabled=None``: show it only on a terminal."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        yield from items
        return
    from tqdm import tqdm

    bar = tqdm(items, total=total, desc=desc, unit="frame", file=sys.stderr, leave=False, dynamic_ncols=True)
    try:
        yield from bar
    finally:
        bar.close()
