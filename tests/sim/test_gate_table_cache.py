"""`table_cache.cached_table` as the axial and clearance tables use it: a file that cannot be read (not an
archive, without the "present" flag, or without a table's array) is a `TssCacheError` naming the table's
kind and the file, and is not rebuilt over; "no table" files and the saved arrays read back as written."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from servoface.sim.gate.axial import AxialTable, cached_axial
from servoface.sim.gate.clearance import Clearance, cached_clearance
from servoface.sim.gate.errors import TssCacheError

AXIAL = AxialTable(np.array([0, 2], dtype=np.int64), np.array([1.0, -1.0]), 0.0, 10.0, 10.0, np.array([1.0, 0.5]))
CLEARANCE = Clearance(
    "x",
    np.zeros(3),
    1.0,
    np.array([0, 2], dtype=np.int64),
    np.array([0.0, 5.0]),
    np.array([10.0, 0.0]),
    np.array([3, 2], dtype=np.int64),
    np.array([10.0, 10.0]),
    np.array([1.0, 1.0, 0.5, 0.5, 0.0, 0.0]),
)
KINDS: list[tuple[str, Callable[..., Any], Any, list[str]]] = [
    ("axial", cached_axial, AXIAL, ["present", "joints", "coef", "lower", "step", "arm", "slack"]),
    (
        "clearance",
        cached_clearance,
        CLEARANCE,
        ["present", "ball_part", "centre", "radius", "joints", "lower", "step", "counts", "arm", "slack"],
    ),
]


def _never() -> Any:
    pytest.fail("rebuilt over a cache file")


@pytest.mark.parametrize(("kind", "cached", "table", "keys"), KINDS, ids=[k[0] for k in KINDS])
def test_unreadable_cache_files_are_errors_naming_kind_and_file(
    kind: str, cached: Callable[..., Any], table: Any, keys: list[str], tmp_path: Path
) -> None:
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not an archive")
    with pytest.raises(TssCacheError, match=f"^{kind} cache file .*garbage.npz is unreadable") as err:
        cached(garbage, _never)
    assert isinstance(err.value.__cause__, ValueError)
    unflagged = tmp_path / "unflagged.npz"
    np.savez(unflagged, joints=table.joints)
    with pytest.raises(TssCacheError, match="'present' is not a file|present is not a file") as err:
        cached(unflagged, _never)
    assert isinstance(err.value.__cause__, KeyError)
    short = tmp_path / "short.npz"
    np.savez(short, present=True)
    with pytest.raises(TssCacheError, match=f"^{kind} cache file .*short.npz is unreadable .*{keys[1]}"):
        cached(short, _never)
    folder = tmp_path / "folder.npz"
    folder.mkdir()
    with pytest.raises(TssCacheError, match="delete it to rebuild$") as err:
        cached(folder, _never)
    assert isinstance(err.value.__cause__, OSError)


@pytest.mark.parametrize(("kind", "cached", "table", "keys"), KINDS, ids=[k[0] for k in KINDS])
def test_saved_arrays_and_no_table_files(
    kind: str, cached: Callable[..., Any], table: Any, keys: list[str], tmp_path: Path
) -> None:
    path = tmp_path / f"{kind}.npz"
    assert cached(path, lambda: table) is table
    with np.load(path) as z:
        assert list(z.keys()) == keys and bool(z["present"])
    back = cached(path, _never)
    assert type(back) is type(table)
    for name, value in vars(table).items():
        assert np.array_equal(getattr(back, name), value) and type(getattr(back, name)) is type(value), name
    none = tmp_path / f"{kind}-none.npz"
    assert cached(none, lambda: None) is None
    with np.load(none) as z:
        assert list(z.keys()) == ["present"] and not bool(z["present"])
    assert cached(none, _never) is None
    assert cached(None, lambda: table) is table and cached(None, lambda: None) is None
