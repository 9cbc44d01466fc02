"""TSS broad phase at run time: only the tabulated sphere pairs, transformed by the current joints.

All pairs' tables are concatenated into one list of sphere-pair tests, so one frame is a handful of numpy
calls (gather transforms, transform the used sphere centres, one distance per table entry) and a batch of
k commands is the same calls with a leading axis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.axial import AxialSet
from servoface.sim.gate.clearance import ClearanceSet
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.spheres import SphereSet
from servoface.sim.gate.tss_build import BuiltPair

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


class TssBroadPhase:
    """Flags the part pairs whose tabulated spheres overlap (or whose joints left the swept box)."""

    def __init__(
        self,
        tree: JointTree,
        part_joint: dict[str, str | None],
        pairs: Sequence[BuiltPair],
        always: Sequence[bool] | None = None,
        clearance: ClearanceSet | None = None,
        axial: AxialSet | None = None,
        distance: ClearanceSet | None = None,
        proven_pairs: Sequence[int] = (),
    ) -> None:
        """``always[p]``: pair p skips the sphere tests and always goes to the exact test (tables too
        large to pay off, e.g. a part on the head base against one behind three neck joints) when the
        parts' bounding balls meet — unless ``clearance`` (tables for some of those pairs) proves the pose
        clear. ``axial``: distance tables for pairs turning about one line; where one proves the pose apart
        the pair is not flagged, whatever the spheres or balls say (inside its grid only). ``distance``: tables
        over a pair's relative joints (`joint_tables`): a pair with sphere tests gets none, it is flagged
        wherever its table does not prove the pose apart (outside the grid too); an exact-only pair's met
        balls are cleared where its table proves the pose apart. ``proven_pairs``: exact-only
        pairs proven apart inside their joint box (`joint_tables.plane_separated`): flagged only outside it."""
        self.pairs = tuple(pairs)
        self.axial = axial if axial is not None and len(axial) else None
        self._ax_pairs = [(int(p), t) for t, p in enumerate(self.axial.pair_index)] if self.axial is not None else []
        self.distance = distance if distance is not None and len(distance) else None
        self.clearance = clearance if clearance is not None and len(clearance) else None
        self.always = np.zeros(len(self.pairs), dtype=bool) if always is None else np.array(always, dtype=bool)
        # a distance table of a pair with sphere tests replaces them: the pair is flagged wherever its table
        # does not prove the pose apart (outside its grid too); of an exact-only pair, it clears met balls
        dist_pairs = [(int(p), t) for t, p in enumerate(self.distance.pair_index)] if self.distance is not None else []
        self._dist_or = [(p, t) for p, t in dist_pairs if not self.always[p]]
        self._dist_and = [(p, t) for p, t in dist_pairs if self.always[p]]
        self._dist_or_idx = np.array([p for p, _ in self._dist_or], dtype=np.int64)
        self._dist_or_t = np.array([t for _, t in self._dist_or], dtype=np.int64)
        self._dist_and_idx = np.array([p for p, _ in self._dist_and], dtype=np.int64)
        self._dist_and_t = np.array([t for _, t in self._dist_and], dtype=np.int64)
        self.table_only = np.zeros(len(self.pairs), dtype=bool)  # no sphere tests: the distance table decides
        self.table_only[self._dist_or_idx] = True
        spheres_skipped = self.always | self.table_only
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
            if spheres_skipped[p]:
                continue
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
        # group the spheres by the joint that carries them: one small matmul per group per frame
        order = np.argsort(self.slot, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        self.centres_h = self.centres_h[order]
        self.slot = self.slot[order]
        self.ga, self.gb = rank[self.ga], rank[self.gb]
        cuts = np.flatnonzero(np.diff(self.slot)) + 1
        bounds = np.r_[0, cuts, len(self.slot)].astype(np.int64)
        self._groups = [
            (int(self.slot[a]), int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a
        ]
        # swept boxes as (P, J) bounds (+-inf for joints a pair does not sweep), for the fallback
        self._lo = np.full((len(self.pairs), n_joints), -np.inf)
        self._hi = np.full((len(self.pairs), n_joints), np.inf)
        for p, b in enumerate(self.pairs):
            idx = [tree.index[j] for j in b.table.joints]
            self._lo[p, idx] = b.table.lower_deg - 1e-9
            self._hi[p, idx] = b.table.upper_deg + 1e-9
        self.n_tests = int(self.ga.shape[0])
        counts = np.array(
            [0 if spheres_skipped[p] else b.table.n_tests for p, b in enumerate(self.pairs)], dtype=np.int64
        )
        self._nonempty = counts > 0
        self._starts = (np.cumsum(counts) - counts)[self._nonempty]
        # exact-only pairs still get a cheap gate: the parts' bounding balls (around all their spheres)
        # pairs a clearance table proves apart inside their box need nothing but the box test; the others
        # with a table are cleared per pose where their balls meet
        proven = {int(p) for p in proven_pairs}
        table_of: dict[int, int] = {}
        if self.clearance is not None:
            proven |= {int(p) for p, ok in zip(self.clearance.pair_index, self.clearance.proven, strict=True) if ok}
            table_of = {int(p): t for t, p in enumerate(self.clearance.pair_index) if int(p) not in proven}
        self.proven = np.array([p in proven for p in range(len(self.pairs))], dtype=bool)
        balls = []
        for p, built in enumerate(self.pairs):
            if not self.always[p] or p in proven:
                continue
            t = built.table
            ja, jb = part_joint[t.a], part_joint[t.b]
            (ca, ra), (cb, rb) = _ball(built.spheres_a), _ball(built.spheres_b)
            balls.append(
                (
                    p,
                    n_joints if ja is None else tree.index[ja],
                    n_joints if jb is None else tree.index[jb],
                    ca,
                    cb,
                    ra + rb + t.tolerance_mm,
                )
            )
        self._always_idx = np.array([b[0] for b in balls], dtype=np.int64)
        self._ball_slot_a = np.array([b[1] for b in balls], dtype=np.int64)
        self._ball_slot_b = np.array([b[2] for b in balls], dtype=np.int64)
        self._ball_a = np.array([np.r_[b[3], 1.0] for b in balls]).reshape(-1, 4)
        self._ball_b = np.array([np.r_[b[4], 1.0] for b in balls]).reshape(-1, 4)
        self._ball_reach = np.array([b[5] for b in balls], dtype=np.float64)
        rows = [(r, table_of[b[0]]) for r, b in enumerate(balls) if b[0] in table_of]
        self._cl_rows = np.array([r for r, _ in rows], dtype=np.int64)  # positions in the ball list
        self._cl_tables = np.array([t for _, t in rows], dtype=np.int64)
        self._cl_pairs = [(r, t) for r, t in rows]
        # per pair, for the relative-frame evaluation: a's used spheres (homogeneous, a's rest frame),
        # b's used spheres (b's rest frame), local index pairs and squared reach
        self._per_pair: list[
            tuple[int, int, int, FloatArray, FloatArray, NDArray[np.int64], NDArray[np.int64], FloatArray]
        ] = []
        for p, built in enumerate(self.pairs):
            t = built.table
            if spheres_skipped[p] or t.n_tests == 0:
                continue
            ua, inv_a = np.unique(t.ia, return_inverse=True)
            ub, inv_b = np.unique(t.ib, return_inverse=True)
            ja, jb = part_joint[t.a], part_joint[t.b]
            r = built.spheres_a.radii_mm[t.ia] + built.spheres_b.radii_mm[t.ib] + t.tolerance_mm
            self._per_pair.append(
                (
                    p,
                    n_joints if ja is None else tree.index[ja],
                    n_joints if jb is None else tree.index[jb],
                    np.c_[built.spheres_a.centres_mm[ua], np.ones(len(ua))],
                    np.ascontiguousarray(built.spheres_b.centres_mm[ub]),
                    inv_a.reshape(-1).astype(np.int64),
                    inv_b.reshape(-1).astype(np.int64),
                    r * r,
                )
            )

    def out_of_box(self, angles_deg: FloatArray) -> BoolArray:
        """(..., n_pairs) True where a pair's joints left the swept box (its table is then not valid)."""
        a = angles_deg[..., None, :]
        return np.asarray(np.any((a < self._lo) | (a > self._hi), axis=-1), dtype=bool)

    def centres(self, world: FloatArray) -> FloatArray:
        """(..., S, 3) posed centres of the tabulated spheres; ``world`` (..., J, 4, 4)."""
        lead = world.shape[:-3]
        out = np.empty((*lead, len(self.slot), 3))
        n_joints = world.shape[-3]
        for slot, a, b in self._groups:
            if slot == n_joints:
                out[..., a:b, :] = self.centres_h[a:b, :3]
            else:
                t = world[..., slot, :3, :]  # (..., 3, 4)
                out[..., a:b, :] = self.centres_h[a:b] @ np.swapaxes(t, -1, -2)
        return out

    def _centres_records(self, world: FloatArray) -> FloatArray:
        """(S, 4) `centres` of one pose ((J, 4, 4)) with a zero fourth column (the same products)."""
        out = np.zeros((len(self.slot), 4))
        n_joints = world.shape[-3]
        for slot, a, b in self._groups:
            if slot == n_joints:
                out[a:b, :3] = self.centres_h[a:b, :3]
            else:
                out[a:b, :3] = self.centres_h[a:b] @ world[slot, :3, :].T
        return out

    def overlaps(self, world: FloatArray) -> BoolArray:
        """(..., n_pairs) True where some tabulated sphere pair overlaps; ``world`` (..., J, 4, 4)."""
        if math.prod(world.shape[:-3]) <= 4:  # (plain ints: numpy's prod cost more than the test)
            return self._overlaps_flat(world)
        return self._overlaps_per_pair(world)

    def _overlaps_flat(self, world: FloatArray) -> BoolArray:
        """Few commands: every table entry in one gather (fewest numpy calls)."""
        lead = world.shape[:-3]
        out = np.zeros((*lead, self.n_pairs), dtype=bool)
        if not self.n_tests:
            return out
        if not lead:  # one command: each centre a 32-byte record (x, y, z, 0), gathered whole by `take`
            d = self._centres_records(world)
            rec = d.view(_RECORD).reshape(-1)
            d = rec.take(self.ga).view(np.float64).reshape(-1, 4)
            d -= rec.take(self.gb).view(np.float64).reshape(-1, 4)
            d *= d
            d2 = d[:, 0] + d[:, 1]  # (dx * dx + dy * dy) + dz * dz, as the batch path sums them
            d2 += d[:, 2]
            close = d2 <= self.thr2
        else:
            c = self.centres(world)
            d = c[..., self.ga, :] - c[..., self.gb, :]
            close = np.einsum("...ei,...ei->...e", d, d) <= self.thr2
        if self.n_tests:
            out[..., self._nonempty] = np.logical_or.reduceat(close, self._starts, axis=-1)
        return out

    def _overlaps_per_pair(self, world: FloatArray) -> BoolArray:
        """Many commands: each pair in b's rest frame.

        Each pair is evaluated in b's rest frame: only a's tabulated spheres move (by inv(T_b) T_a), b's
        stay where the table has them, so one small product and one gather per pair.
        """
        lead = world.shape[:-3]
        flat = world.reshape(-1, *world.shape[-3:])
        k = flat.shape[0]
        eye = np.broadcast_to(np.eye(4), (k, 4, 4))
        out = np.zeros((self.n_pairs, k), dtype=bool)
        for p, sa, sb, xa, yb, ia, ib, thr2 in self._per_pair:
            ta = eye if sa == world.shape[-3] else flat[:, sa]
            tb = eye if sb == world.shape[-3] else flat[:, sb]
            rt = np.swapaxes(tb[:, :3, :3], 1, 2)  # inverse rotation of b
            rel_r = rt @ ta[:, :3, :3]
            rel_t = np.einsum("kij,kj->ki", rt, ta[:, :3, 3] - tb[:, :3, 3])
            rel = np.concatenate([rel_r, rel_t[:, :, None]], axis=2)  # (K, 3, 4)
            ca = np.tensordot(xa, rel, axes=([1], [2]))  # (na, K, 3)
            d = ca[ia] - yb[ib][:, None, :]  # (E, K, 3)
            close = np.einsum("eki,eki->ek", d, d) <= thr2[:, None]
            out[p] = close.any(axis=0)
        return out.T.reshape(*lead, self.n_pairs)

    def flag(self, world: FloatArray, angles_deg: FloatArray) -> BoolArray:
        """Pairs that need the exact test: overlapping tabulated spheres, joints outside the swept box, or
        (untabulated pairs) meeting bounding balls — fcl's own BVH then settles those in microseconds."""
        out = self.overlaps(world) | self.out_of_box(angles_deg) | self.balls_meet(world, angles_deg)
        ax, dist = self.axial, self.distance
        if world.shape[:-3]:
            if ax is not None:
                out[..., ax.pair_index] &= ~ax.clear(angles_deg)
            if dist is not None:
                clear = dist.clear(angles_deg)
                out[..., self._dist_or_idx] |= ~clear[..., self._dist_or_t]
                out[..., self._dist_and_idx] &= ~clear[..., self._dist_and_t]
            return out
        q: list[float] | None = None
        if ax is not None and out[ax.pair_index].any():
            q = angles_deg.tolist()
            for p, t in self._ax_pairs:
                if out[p] and ax.clear_one(t, q):
                    out[p] = False
        if dist is not None:
            q = angles_deg.tolist() if q is None else q
            for p, t in self._dist_or:
                if not out[p] and not dist.clear_one(t, q):
                    out[p] = True
            for p, t in self._dist_and:
                if out[p] and dist.clear_one(t, q):
                    out[p] = False
        return out

    def balls_meet(self, world: FloatArray, angles_deg: FloatArray | None = None) -> BoolArray:
        """(..., n_pairs) True for exact-only pairs whose bounding balls overlap (False elsewhere); with
        ``angles_deg``, pairs whose clearance table proves the pose clear are False too."""
        lead = world.shape[:-3]
        out = np.zeros((*lead, self.n_pairs), dtype=bool)
        if not len(self._always_idx):
            return out
        if lead:
            eye = np.broadcast_to(np.eye(4), (*lead, 1, 4, 4))
            full = np.concatenate([world, eye], axis=-3)
        else:  # one pose: the base's identity appended as is (no broadcast view)
            full = np.concatenate([world, _EYE1], axis=-3)
        ca = np.einsum("...bij,bj->...bi", full[..., self._ball_slot_a, :3, :], self._ball_a)
        cb = np.einsum("...bij,bj->...bi", full[..., self._ball_slot_b, :3, :], self._ball_b)
        d = ca - cb
        # |d| as np.linalg.norm computes it for real arrays (sqrt of the sum of squares), without its checks
        meet = np.sqrt(np.add.reduce(d * d, axis=-1)) <= self._ball_reach
        cl = self.clearance
        if cl is not None and angles_deg is not None and self._cl_pairs:
            if lead:
                meet[..., self._cl_rows] &= ~cl.clear(angles_deg)[..., self._cl_tables]
            elif meet[self._cl_rows].any():
                q = angles_deg.tolist()
                for r, t in self._cl_pairs:
                    if meet[r] and cl.clear_one(t, q):
                        meet[r] = False
        out[..., self._always_idx] = meet
        return out


_RECORD = np.dtype((np.void, 32))  # one sphere centre: x, y, z, 0 as float64
_EYE1 = np.eye(4)[None]  # the head base's transform, appended to one pose's (J, 4, 4)
_EYE1.flags.writeable = False


def _ball(spheres: SphereSet) -> tuple[FloatArray, float]:
    """A ball holding every sphere of a set: (centre (3,), radius)."""
    c = (spheres.centres_mm.min(axis=0) + spheres.centres_mm.max(axis=0)) / 2.0
    return c, float(np.max(np.linalg.norm(spheres.centres_mm - c, axis=1) + spheres.radii_mm))
