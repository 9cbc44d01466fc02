"""Part-pair collisions for the gate: which pairs, their TSS tables (cached), broad phase, exact test."""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.axial import AXIAL_VERSION, AxialSet, AxialTable, build_axial, cached_axial
from servoface.sim.gate.clearance import (
    CLEARANCE_VERSION,
    Clearance,
    ClearanceSet,
    build_clearance,
    cached_clearance,
)
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.exact import ExactCollider, eroded
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.joint_tables import DISTANCE_VERSION, build_distance_table, cached_distance, plane_separated
from servoface.sim.gate.joint_tables import MAX_JOINTS as DISTANCE_MAX_JOINTS
from servoface.sim.gate.proofs import concentric_separation
from servoface.sim.gate.spheres import SphereSet
from servoface.sim.gate.tss_build import BuiltPair, TssParams, build_or_load, relative_joints
from servoface.sim.gate.tss_runtime import TssBroadPhase

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PairSpec:
    """Two parts the gate keeps apart. ``tolerance_mm``: contact up to this depth is allowed (both meshes
    are eroded by half of it, for the TSS and the exact test alike) — e.g. lids riding on an eyeball."""

    a: str
    b: str
    tolerance_mm: float = 0.0


def auto_pairs(head: Any, tree: JointTree) -> list[PairSpec]:
    """Pairs to check when the profile names none: every two colliding parts that move relative to each
    other (a head may list them as ``head.collision_pairs``: (a, b) or (a, b, tolerance_mm))."""
    declared = getattr(head, "collision_pairs", None)
    if declared:
        out = []
        for item in declared:
            if isinstance(item, PairSpec):
                out.append(item)
            else:
                t = tuple(item)
                out.append(PairSpec(str(t[0]), str(t[1]), float(t[2]) if len(t) > 2 else 0.0))
        return out
    parts = [p for p in head.parts if getattr(p, "collides", True)]
    return [
        PairSpec(a.name, b.name) for a, b in itertools.combinations(parts, 2) if relative_joints(tree, a.joint, b.joint)
    ]


class PartCollisions:
    """TSS broad phase + fcl exact test over a head's checked part pairs (rest meshes, head frame)."""

    def __init__(
        self,
        head: Any,
        tree: JointTree,
        pairs: Sequence[PairSpec],
        params: TssParams,
        cache_dir: Path | None,
        drop_touching_at_rest: bool = True,
        clearance: bool = True,
    ) -> None:
        """``clearance``: pairs without a table get clearance tables where they pay (`clearance`); False
        sends them to the exact test whenever their bounding balls meet (the straightforward path)."""
        parts = {p.name: p for p in head.parts}
        for spec in pairs:
            for name in (spec.a, spec.b):
                if name not in parts:
                    raise GateConfigError(
                        f"collision pair ({spec.a}, {spec.b}): head '{head.name}' has no part "
                        f"'{name}'; parts {sorted(parts)}"
                    )
        self.tree = tree
        self._cache_dir, self._head_name = cache_dir, head.name
        self.part_joint = {name: p.joint for name, p in parts.items()}
        meshes: dict[str, Any] = {}
        built: list[BuiltPair] = []
        covers: dict[int, tuple[Any, SphereSet]] = {}
        self.specs: list[PairSpec] = []
        self.skipped: list[tuple[PairSpec, str]] = []
        rest = np.broadcast_to(np.eye(4), (len(tree.names), 4, 4))
        for spec in pairs:
            ma = meshes.setdefault(f"{spec.a}@{spec.tolerance_mm}", eroded(parts[spec.a].mesh, spec.tolerance_mm))
            mb = meshes.setdefault(f"{spec.b}@{spec.tolerance_mm}", eroded(parts[spec.b].mesh, spec.tolerance_mm))
            reason = concentric_separation(
                tree,
                parts[spec.a].joint,
                parts[spec.b].joint,
                ma,
                mb,
                relative_joints(tree, parts[spec.a].joint, parts[spec.b].joint),
            )
            if reason is not None:
                self.skipped.append((spec, reason))
                continue
            self.specs.append(spec)
            built.append(
                build_or_load(
                    tree,
                    head.name,
                    parts[spec.a],
                    parts[spec.b],
                    ma,
                    mb,
                    spec.tolerance_mm,
                    params,
                    cache_dir,
                    covers,
                )
            )
        self.exact = ExactCollider(meshes)
        self._meshes = meshes
        self._last_exact: dict[tuple[str, str, float], tuple[bytes, bool]] = {}
        keep = []
        for spec, b in zip(self.specs, built, strict=True):
            if b.table.n_tests == 0 and not b.table.exact_only:
                keep.append(True)  # never close anywhere in its joint space: costs nothing
                continue
            touching = self._collide(spec, self._neutral_world(rest))
            if touching and drop_touching_at_rest:
                self.skipped.append((spec, "in contact at the neutral pose (give it a tolerance_mm)"))
                keep.append(False)
            else:
                keep.append(True)
        self.specs = [s for s, k in zip(self.specs, keep, strict=True) if k]
        self.built = [b for b, k in zip(built, keep, strict=True) if k]
        self.always = [b.table.exact_only or b.table.n_tests > params.max_table_tests for b in self.built]
        self.clearance = self._clearance_tables(parts, meshes) if clearance else ClearanceSet([], [])
        self.axial = self._axial_tables(parts) if clearance else AxialSet([], [])
        self.plane_proven: list[tuple[int, str]] = self._plane_proofs(parts) if clearance else []
        self.distance = self._distance_tables(parts) if clearance else ClearanceSet([], [])
        self.broad = TssBroadPhase(
            tree,
            self.part_joint,
            self.built,
            self.always,
            self.clearance,
            self.axial,
            self.distance,
            [p for p, _ in self.plane_proven],
        )
        self.pairs_active = [
            s for s, b in zip(self.specs, self.built, strict=True) if b.table.n_tests > 0 or b.table.exact_only
        ]

    def _clearance_tables(self, parts: dict[str, Any], meshes: dict[str, Any]) -> ClearanceSet:
        """Clearance tables for the pairs that skip the sphere tests (built from their covers, in ms)."""
        index, tables = [], []
        for p, (spec, b, always) in enumerate(zip(self.specs, self.built, self.always, strict=True)):
            if not always:
                continue
            path = None
            if self._cache_dir is not None:
                name = f"{self._head_name}-{spec.a}-{spec.b}-{b.table.key}-{CLEARANCE_VERSION}.npz"
                path = self._cache_dir / name
            got = cached_clearance(path, functools.partial(self._build_clearance, parts, meshes, spec, b))
            if got is not None:
                index.append(p)
                tables.append(got)
        return ClearanceSet(index, tables)

    def _axial_tables(self, parts: dict[str, Any]) -> AxialSet:
        """Distance tables (`axial`) for the pairs the broad phase can flag whose relative joints turn about
        one line (the lid pairs), unless a clearance table already proves them apart."""
        proven = {int(p) for p, ok in zip(self.clearance.pair_index, self.clearance.proven, strict=True) if ok}
        index, tables = [], []
        for p, (spec, b, always) in enumerate(zip(self.specs, self.built, self.always, strict=True)):
            if p in proven or not (always or b.table.n_tests > 0):
                continue
            path = None
            if self._cache_dir is not None:
                name = f"{self._head_name}-{spec.a}-{spec.b}-{b.table.key}-{AXIAL_VERSION}.npz"
                path = self._cache_dir / name
            got = cached_axial(path, functools.partial(self._build_axial, parts, spec))
            if got is not None:
                index.append(p)
                tables.append(got)
        return AxialSet(index, tables)

    def _needs_exact(self) -> list[int]:
        """Pairs the broad phase can send to the exact test that no clearance or axial table covers."""
        covered = {int(p) for p, ok in zip(self.clearance.pair_index, self.clearance.proven, strict=True) if ok}
        covered |= {int(p) for p in self.axial.pair_index}
        return [
            p
            for p, (b, always) in enumerate(zip(self.built, self.always, strict=True))
            if p not in covered and (always or b.table.n_tests > 0)
        ]

    def _plane_proofs(self, parts: dict[str, Any]) -> list[tuple[int, str]]:
        """(pair index, reason) of the exact-only pairs (no sphere table: their bounding balls decide) kept
        apart by a plane inside their joint limits (`joint_tables`): the broad phase flags them only outside."""
        out = []
        for p in self._needs_exact():
            if not self.always[p]:
                continue
            spec = self.specs[p]
            na, nb = f"{spec.a}@{spec.tolerance_mm}", f"{spec.b}@{spec.tolerance_mm}"
            ja, jb = parts[spec.a].joint, parts[spec.b].joint
            reason = plane_separated(self.tree, ja, jb, self._meshes[na], self._meshes[nb])
            if reason is not None:
                out.append((p, reason))
        return out

    def _distance_tables(self, parts: dict[str, Any]) -> ClearanceSet:
        """Distance tables (`joint_tables`) for the pairs left to the exact test whose relative joints are few."""
        proven = {p for p, _ in self.plane_proven}
        index, tables = [], []
        for p in self._needs_exact():
            spec, b = self.specs[p], self.built[p]
            if p in proven or p in {int(i) for i in self.clearance.pair_index}:
                continue
            ja, jb = parts[spec.a].joint, parts[spec.b].joint
            rel = relative_joints(self.tree, ja, jb)
            if len(rel) > DISTANCE_MAX_JOINTS:
                continue
            path = None
            if self._cache_dir is not None:
                name = f"{self._head_name}-{spec.a}-{spec.b}-{b.table.key}-{DISTANCE_VERSION}.npz"
                path = self._cache_dir / name
            na, nb = f"{spec.a}@{spec.tolerance_mm}", f"{spec.b}@{spec.tolerance_mm}"
            build = functools.partial(
                build_distance_table,
                self.tree,
                ja,
                jb,
                rel,
                self._meshes[na],
                self._meshes[nb],
                functools.partial(self.exact.distance, na, nb),
            )
            got = cached_distance(path, build)
            if got is not None:
                index.append(p)
                tables.append(got)
        return ClearanceSet(index, tables)

    def _build_axial(self, parts: dict[str, Any], spec: PairSpec) -> AxialTable | None:
        ja, jb = parts[spec.a].joint, parts[spec.b].joint
        na, nb = f"{spec.a}@{spec.tolerance_mm}", f"{spec.b}@{spec.tolerance_mm}"
        return build_axial(
            self.tree,
            ja,
            jb,
            relative_joints(self.tree, ja, jb),
            self._meshes[na],
            self._meshes[nb],
            functools.partial(self.exact.distance, na, nb),
        )

    def _build_clearance(
        self, parts: dict[str, Any], meshes: dict[str, Any], spec: PairSpec, b: BuiltPair
    ) -> Clearance | None:
        return build_clearance(
            self.tree,
            parts[spec.a],
            parts[spec.b],
            meshes[f"{spec.a}@{spec.tolerance_mm}"],
            meshes[f"{spec.b}@{spec.tolerance_mm}"],
            b.spheres_a,
            b.spheres_b,
        )

    def _neutral_world(self, rest: FloatArray) -> FloatArray:
        return np.asarray(self.tree.world(self.tree.neutral_deg[None, :])[0], dtype=np.float64)

    def part_transform(self, name: str, world: FloatArray) -> FloatArray:
        j = self.part_joint[name]
        return np.eye(4) if j is None else world[self.tree.index[j]]

    def _collide(self, spec: PairSpec, world: FloatArray) -> bool:
        """The exact test of one pair; the last answer per pair is kept and reused when both parts sit
        exactly where they sat then (the same inputs: e.g. still lids while the mouth moves)."""
        ta, tb = self.part_transform(spec.a, world), self.part_transform(spec.b, world)
        key = ta.tobytes() + tb.tobytes()
        last = self._last_exact.get((spec.a, spec.b, spec.tolerance_mm))
        if last is not None and last[0] == key:
            return last[1]
        hit = self.exact.collide(f"{spec.a}@{spec.tolerance_mm}", f"{spec.b}@{spec.tolerance_mm}", ta, tb)
        self._last_exact[(spec.a, spec.b, spec.tolerance_mm)] = (key, hit)
        return hit

    def colliding(self, world: FloatArray, angles_deg: FloatArray) -> tuple[list[PairSpec], int]:
        """(pairs in collision by the exact test, number of pairs the broad phase flagged) for one pose."""
        flags = self.broad.flag(world, angles_deg)
        hit = [self.specs[p] for p in np.nonzero(flags)[0] if self._collide(self.specs[p], world)]
        return hit, int(flags.sum())

    def colliding_exhaustive(self, world: FloatArray) -> list[PairSpec]:
        """Exact test on every checked pair, no broad phase (for tests and audits)."""
        return [s for s in self.specs if self._collide(s, world)]

    @property
    def n_tests(self) -> int:
        """Sphere-pair tests per frame (pairs sent straight to the exact test not counted)."""
        return self.broad.n_tests

    @property
    def n_all_sphere_pairs(self) -> int:
        """All sphere pairs of the pairs the TSS handles (the brute-force count it is compared with)."""
        return sum(b.table.n_all_pairs for b, a in zip(self.built, self.always, strict=True) if not a)

    @property
    def exact_always(self) -> list[PairSpec]:
        """Pairs that skip the sphere tests (no table, or one too large)."""
        return [s for s, a in zip(self.specs, self.always, strict=True) if a]
