"""TSS broad phase at run time: only the tabulated sphere pairs, transformed by the current joints.

All pairs' tables are concatenated into one list of sphere-pair tests, so one frame is a handful of numpy
calls (gather transforms, transform the used sphere centres, one distance per table entry) and a batch of
k commands is the same calls with a leading axis.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from sim.gate.fk import JointTree
from sim.gate.tss_build import BuiltPair

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class TssBroadPhase:
    """Flags the part pairs whose tabulated spheres overlap (or whose joints left the swept box)."""

    def __init__(
        self, tree: JointTree, part_joint: dict[str, str | None], pairs: Sequence[BuiltPair]
    ) -> None:
        self.pairs = tuple(pairs)
        n_joints = len(tree.names)
        centres: list[FloatArray] = []
        slot: list[int] = []
        ga: list[NDArray[np.int64]] = []
        gb: list[NDArray[np.int64]] = []
        thr: list[FloatArray] = []
        pid: list[NDArray[np.int64]] = []
        offset = 0
        for p, built in enumerate(self.pairs):
            t = built.table
            ua, inv_a = np.unique(t.ia, return_inverse=True)
            ub, inv_b = np.unique(t.ib, return_inverse=True)
            ja, jb = part_joint[t.a], part_joint[t.b]
            centres += [built.spheres_a.centres_mm[ua], built.spheres_b.centres_mm[ub]]
            slot += [n_joints if ja is None else tree.index[ja]] * len(ua)
            slot += [n_joints if jb is None else tree.index[jb]] * len(ub)
            ga.append(offset + inv_a.reshape(-1))
            gb.append(offset + len(ua) + inv_b.reshape(-1))
            offset += len(ua) + len(ub)
            r = built.spheres_a.radii_mm[t.ia] + built.spheres_b.radii_mm[t.ib] + t.tolerance_mm
            thr.append(r * r)
            pid.append(np.full(t.n_tests, p, dtype=np.int64))
        self.n_pairs = len(self.pairs)
        self.centres_h = np.c_[np.concatenate(centres), np.ones(offset)] if offset else np.zeros((0, 4))
        self.slot = np.array(slot, dtype=np.int64)
        self.ga = np.concatenate(ga) if ga else np.zeros(0, np.int64)
        self.gb = np.concatenate(gb) if gb else np.zeros(0, np.int64)
        self.thr2 = np.concatenate(thr) if thr else np.zeros(0)
        self.pid = np.concatenate(pid) if pid else np.zeros(0, np.int64)
        # swept boxes: per pair, the joints and their bounds (for the out-of-range fallback)
        self._box = [
            (
                np.array([tree.index[j] for j in b.table.joints], dtype=np.int64),
                b.table.lower_deg,
                b.table.upper_deg,
            )
            for b in self.pairs
        ]
        self.n_tests = int(self.ga.shape[0])
        counts = np.array([b.table.n_tests for b in self.pairs], dtype=np.int64)
        self._nonempty = counts > 0
        self._starts = (np.cumsum(counts) - counts)[self._nonempty]

    def out_of_box(self, angles_deg: FloatArray) -> BoolArray:
        """(..., n_pairs) True where a pair's joints left the swept box (its table is then not valid)."""
        out = np.zeros((*angles_deg.shape[:-1], self.n_pairs), dtype=bool)
        for p, (idx, lo, hi) in enumerate(self._box):
            if len(idx):
                a = angles_deg[..., idx]
                out[..., p] = np.any((a < lo - 1e-9) | (a > hi + 1e-9), axis=-1)
        return out

    def overlaps(self, world: FloatArray) -> BoolArray:
        """(..., n_pairs) True where some tabulated sphere pair overlaps; ``world`` (..., J, 4, 4)."""
        lead = world.shape[:-3]
        eye = np.broadcast_to(np.eye(4), (*lead, 1, 4, 4))
        transforms = np.concatenate([world, eye], axis=-3)[..., self.slot, :, :]  # (..., S, 4, 4)
        c = np.einsum("...sij,sj->...si", transforms[..., :3, :], self.centres_h)
        d = c[..., self.ga, :] - c[..., self.gb, :]
        close = np.einsum("...ei,...ei->...e", d, d) <= self.thr2
        out = np.zeros((*lead, self.n_pairs), dtype=bool)
        if self.n_tests:
            out[..., self._nonempty] = np.logical_or.reduceat(close, self._starts, axis=-1)
        return out

    def flag(self, world: FloatArray, angles_deg: FloatArray) -> BoolArray:
        """Pairs that need the exact test: overlapping tabulated spheres or outside the swept box."""
        return self.overlaps(world) | self.out_of_box(angles_deg)
