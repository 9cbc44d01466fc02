"""Batched forward kinematics of a head's joint tree (numpy, no per-command Python loop over commands).

A joint with pivot p and unit axis a (head frame, every joint at 0 deg) rotated by theta has the world
transform  T_parent @ Trans(p) @ Rot(a, theta) @ Trans(-p)  — the convention of `servoface.sim.rig`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError

FloatArray = NDArray[np.float64]


class JointTree:
    """The joints of a head in parent-first order, ready for batched transforms."""

    def __init__(self, joints: Sequence[Any]) -> None:
        by_name = {j.name: j for j in joints}
        order: list[str] = []
        seen: set[str] = set()

        def visit(name: str, stack: tuple[str, ...]) -> None:
            if name in seen:
                return
            if name in stack:
                raise GateConfigError(f"joint tree has a cycle through {list(stack)}")
            parent = by_name[name].parent
            if parent is not None:
                if parent not in by_name:
                    raise GateConfigError(f"joint '{name}': unknown parent '{parent}'")
                visit(parent, (*stack, name))
            seen.add(name)
            order.append(name)

        for j in joints:
            visit(j.name, ())
        self.names: tuple[str, ...] = tuple(order)
        self.index = {n: i for i, n in enumerate(self.names)}
        self.parent_index = np.array(
            [-1 if by_name[n].parent is None else self.index[by_name[n].parent] for n in self.names],
            dtype=np.int64,
        )
        self.pivot_mm = np.array([by_name[n].pivot_mm for n in self.names], dtype=np.float64).reshape(-1, 3)
        axes = np.array([by_name[n].axis for n in self.names], dtype=np.float64).reshape(-1, 3)
        norms = np.linalg.norm(axes, axis=1)
        if np.any(norms < 1e-9):
            zero = [n for n, v in zip(self.names, norms, strict=True) if v < 1e-9]
            raise GateConfigError(f"joint axes must be non-zero: {zero}")
        self.axis = axes / norms[:, None]
        self.lower_deg = np.array([by_name[n].lower_deg for n in self.names], dtype=np.float64)
        self.upper_deg = np.array([by_name[n].upper_deg for n in self.names], dtype=np.float64)
        self.neutral_deg = np.array([getattr(by_name[n], "neutral_deg", 0.0) for n in self.names], dtype=np.float64)
        self._one: tuple[FloatArray, FloatArray, list[int]] | None = None  # `world_one`'s constants
        self._parents = [int(p) for p in self.parent_index]
        self._levels = _levels(self._parents)

    def world_one(self, angles_deg: FloatArray) -> FloatArray:
        """`world` for one pose: angles (J,) deg -> (J, 4, 4), bit for bit the same numbers (the same
        elementwise Rodrigues terms with the constant axis products kept, the same products down the tree)
        without the batch axis' overhead (the gate's per-frame check poses one command)."""
        loc = self.local_one(angles_deg)
        out = np.empty_like(loc)
        self.fill_levels(out, loc)
        return out

    def fill_levels(self, out: FloatArray, loc: FloatArray) -> None:
        """`fill_one` of every joint, a tree level at a time: the joints of one depth are multiplied in one
        stacked ``matmul`` (the same 4x4 product per joint as `fill_one`'s, so the same numbers) instead of
        one call each, on views where the level allows (`_levels`): the human head's 12 joints are 5 products,
        about half `fill_one`'s time. Fewer calls matter more than the arithmetic here (the per-frame check
        runs with caches cold after each sleep)."""
        for joints, parents in self._levels:
            out[joints] = loc[joints] if parents is None else out[parents] @ loc[joints]

    def local_one(self, angles_deg: FloatArray) -> FloatArray:
        """(J, 4, 4) local transforms of one pose, as `world_one` computes them (`fill_one` chains them)."""
        if self._one is None:
            a = self.axis
            k = np.zeros((a.shape[0], 3, 3))
            k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -a[:, 2], a[:, 1], -a[:, 0]
            k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = a[:, 2], -a[:, 1], a[:, 0]
            self._one = (k, k @ k, [int(p) for p in self.parent_index])
        k, kk, parents = self._one
        th = np.deg2rad(angles_deg)[:, None, None]
        r = np.eye(3) + np.sin(th) * k + (1.0 - np.cos(th)) * kk
        loc = np.zeros((len(parents), 4, 4))
        loc[:, :3, :3] = r
        loc[:, :3, 3] = self.pivot_mm - np.einsum("...ij,...j->...i", r, self.pivot_mm)
        loc[:, 3, 3] = 1.0
        return loc

    def fill_one(self, out: FloatArray, loc: FloatArray, joints: Iterable[int]) -> None:
        """Write the world transforms of ``joints`` (indices, each after its parent: ascending order, or a
        parent already written) into ``out`` from `local_one`'s ``loc``: `world_one`'s products, so a pose
        filled in parts holds its numbers (a caller that needs a few joints first fills them first)."""
        parents = self._parents
        for i in joints:
            p = parents[i]
            out[i] = loc[i] if p < 0 else out[p] @ loc[i]

    def ancestry(self, joints: Iterable[int]) -> list[int]:
        """The given joints and all their ancestors, ascending (parents first: `fill_one`'s order)."""
        return sorted({i for j in joints if j >= 0 for i in self.chain(self.names[j])})

    def chain(self, name: str | None) -> list[int]:
        """Indices of ``name`` and its ancestors (root last); [] for the head base."""
        out: list[int] = []
        i = -1 if name is None else self.index[name]
        while i >= 0:
            out.append(i)
            i = int(self.parent_index[i])
        return out

    def local(self, angles_deg: FloatArray, joints: Sequence[int] | None = None) -> FloatArray:
        """Local transforms (..., J, 4, 4) for angles (..., J) in deg (Rodrigues); with ``joints``, those
        joints' only (angles (..., len(joints)) of those joints; the same arithmetic per joint)."""
        th = np.deg2rad(angles_deg)[..., None, None]
        a = self.axis if joints is None else self.axis[list(joints)]
        pivot = self.pivot_mm if joints is None else self.pivot_mm[list(joints)]
        k = np.zeros((a.shape[0], 3, 3))
        k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -a[:, 2], a[:, 1], -a[:, 0]
        k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = a[:, 2], -a[:, 1], a[:, 0]
        r = np.eye(3) + np.sin(th) * k + (1.0 - np.cos(th)) * (k @ k)
        out = np.zeros((*angles_deg.shape, 4, 4))
        out[..., :3, :3] = r
        out[..., :3, 3] = pivot - np.einsum("...ij,...j->...i", r, np.broadcast_to(pivot, r.shape[:-1]))
        out[..., 3, 3] = 1.0
        return out

    def world(self, angles_deg: FloatArray) -> FloatArray:
        """World transforms (..., J, 4, 4) of every joint for angles (..., J) deg."""
        loc = self.local(angles_deg)
        out = np.empty_like(loc)
        for i, p in enumerate(self.parent_index):
            out[..., i, :, :] = loc[..., i, :, :] if p < 0 else out[..., p, :, :] @ loc[..., i, :, :]
        return out

    def world_of(self, angles_deg: FloatArray, joints: Sequence[int]) -> FloatArray:
        """`world` for angles (..., J), computed only along the chains of ``joints`` (indices; -1 = the
        head base): entries of other joints are left zero. The same products in the same order as `world`
        for the joints it fills (the TSS build needs two parts' transforms on large grids)."""
        need = sorted({i for j in joints if j >= 0 for i in self.chain(self.names[j])})
        out = np.zeros((*angles_deg.shape, 4, 4))
        if not need:
            return out
        loc = self.local(angles_deg[..., need], need)
        for n, i in enumerate(need):
            p = int(self.parent_index[i])
            out[..., i, :, :] = loc[..., n, :, :] if p < 0 else out[..., p, :, :] @ loc[..., n, :, :]
        return out


_Index = Any  # an int, a slice or an index array: what a level's joints and parents are indexed by
_Level = tuple[_Index, _Index | None]  # (joints, their parents); parents None: the roots


def _levels(parents: Sequence[int]) -> list[_Level]:
    """The joints grouped by depth in the tree (roots first), each level with its joints' parents: every
    parent is in an earlier level, so a level's products only read transforms already written. Each index
    is as cheap as it can be: an int for one joint or a shared parent (a broadcast product), a slice for a
    run of consecutive joints (views), an index array only otherwise."""
    depth: list[int] = []
    for p in parents:  # parent-first order: a parent's depth is known before its children's
        depth.append(0 if p < 0 else depth[p] + 1)
    out: list[_Level] = []
    for d in range(max(depth, default=-1) + 1):
        joints = [i for i, k in enumerate(depth) if k == d]
        out.append((_index(joints, False), None if d == 0 else _index([parents[i] for i in joints], True)))
    return out


def _index(items: list[int], shared: bool) -> _Index:
    """``items`` as an int (one item, or with ``shared`` all the same: it broadcasts), a slice (consecutive)
    or an index array."""
    if len(items) == 1 or (shared and len(set(items)) == 1):
        return items[0]
    if items == list(range(items[0], items[0] + len(items))):
        return slice(items[0], items[0] + len(items))
    return np.array(items, dtype=np.int64)
