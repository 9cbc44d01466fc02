"""Skin strain the joints alone decide, tabulated per servo tick.

Most of the skin the strain check watches is never moved by an anchor pull: it only bends where it is
blended between two joints (the skull and the jaw). Its stretch, compression and flips are then a function
of the joint transforms relative to the deepest joint all skinning joints hang from (strain is blind to a
common rigid motion). When those relative transforms are driven by one uncoupled servo, that function is
tabulated here once over every integer tick of that servo, and `SkinTwin.measure_one` measures only the
pull-driven rest per frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.strain import SkinTwin
from servoface.sim.gate.twin import TwinPoser

IntArray = NDArray[np.int64]

_MAX_TICKS = 4096  # one full turn; a wider span is not tabulated
_CHUNK = 64


class StaticSkin:
    """(max squared stretch, min squared stretch, flips) of the joint-only skin, looked up per command."""

    def __init__(
        self, column: int, lo_tick: int, hi2: NDArray[np.float64], lo2: NDArray[np.float64], flips: IntArray
    ) -> None:
        self.column = column
        self.lo_tick = lo_tick
        self._values = [(float(a), float(b), int(c)) for a, b, c in zip(hi2, lo2, flips, strict=True)]

    def values(self, goal: IntArray) -> tuple[float, float, int]:
        """The table entry for one (n,) command (the tick clipped into the servo's limits, as the twin)."""
        i = int(goal[self.column]) - self.lo_tick
        return self._values[min(max(i, 0), len(self._values) - 1)]


def driving_column(skin: SkinTwin, poser: TwinPoser, tree: JointTree) -> int | None:
    """The one uncoupled servo column whose tick decides the skinning joints' relative transforms; -1
    when no servo does (constant), None when several do (no table)."""
    base = len(tree.names)
    chains = [set() if s == base else set(tree.chain(tree.names[s])) for s in skin._used]
    roots = [c for c in chains if all(c <= other for other in chains)]
    if not roots:
        return None
    root = max(roots, key=len)
    joints = set().union(*chains) - root
    cols = {int(c) for c, j in zip(poser._joint_col, poser._joint_idx, strict=True) if int(j) in joints}
    if len(cols) > 1:
        return None
    if not cols:
        return -1
    col = cols.pop()
    return None if bool(poser._coupled[col]) else col


def build_static(skin: SkinTwin, poser: TwinPoser, tree: JointTree) -> StaticSkin | None:
    """Split ``skin`` (see `SkinTwin.split_static`) and tabulate the joint-only part; None (and the skin
    left whole) when no single servo decides it."""
    col = driving_column(skin, poser, tree)
    if col is None:
        return None
    if col >= 0:
        lo, hi = int(poser.min_tick[col]), int(poser.max_tick[col])
        if hi - lo + 1 > _MAX_TICKS:
            return None
        ticks = np.arange(lo, hi + 1, dtype=np.int64)
    else:
        col, lo, ticks = 0, int(poser.neutral_tick[0]), np.array([int(poser.neutral_tick[0])], dtype=np.int64)
    static_e, static_f = skin.split_static()
    parts = []
    for start in range(0, len(ticks), _CHUNK):
        goals = np.tile(poser.neutral_tick, (len(ticks[start : start + _CHUNK]), 1))
        goals[:, col] = ticks[start : start + _CHUNK]
        world = tree.world(poser.joint_angles(poser.targets(goals)))
        parts.append(skin.measure_static(world, static_e, static_f))
    hi2, lo2, flips = (np.concatenate(p) for p in zip(*parts, strict=True))
    if len(ticks) == 1:  # constant: every tick of column 0 maps to the one entry
        return StaticSkin(0, 0, np.full(1, hi2[0]), np.full(1, lo2[0]), np.full(1, flips[0]))
    return StaticSkin(col, lo, hi2, lo2, flips)
