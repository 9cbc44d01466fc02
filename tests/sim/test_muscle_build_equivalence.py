"""The muscle model's build (k-d tree look-ups, local shortest paths, lexsort row groups) gives the same
arrays as the straightforward build it replaced (kept below as the reference: every vertex measured per
muscle and per anchor, the shortest paths over the whole skin up to the full limit, numpy's row unique):
exactly equal, on the built-in heads, on the human head with its skin subdivided (as `bench scale` does),
and on random inputs."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra
from servoface.sim.face_model import FaceModel, as_model_muscle
from servoface.sim.heads import load_head
from servoface.sim.muscles.eyelid import EyelidMuscle
from servoface.sim.muscles.field import MuscleField, _insertion_mm
from servoface.sim.muscles.near import NearVertices
from servoface.sim.muscles.slit import SlitGate, forget_shared_gates, row_groups, slit_gate
from servoface.sim.muscles.sphincter import SphincterMuscle

# --- the reference: the build as it was, straightforward -------------------------------------------------


def _reference_gate(gate: SlitGate, src: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """SlitGate._gate before the local searches: dijkstra over the whole skin up to the full limit."""
    src = np.nonzero(np.isin(gate.representative, gate.representative[src]))[0]
    rest = gate._rest
    reach = 3.0 * float(np.max(np.linalg.norm(rest[idx] - rest[src[0]], axis=1), initial=0.0))
    limit = reach + 2.0 * gate.reach_mm
    cut = np.asarray(dijkstra(gate._cut, indices=src, min_only=True, limit=limit))[idx]
    roots = np.unique(gate.representative[src])
    sewn = np.asarray(dijkstra(gate._sewn, indices=roots, min_only=True, limit=limit))
    sewn = sewn[gate.representative[idx]]
    detour = np.where(np.isfinite(cut) & np.isfinite(sewn), cut - sewn, np.inf)
    detour = np.where(np.isfinite(sewn) & ~np.isfinite(cut), np.inf, detour)
    detour = np.where(~np.isfinite(sewn), 0.0, detour)
    out = np.cos(np.clip(detour / gate.reach_mm, 0.0, 1.0) * (np.pi / 2))
    out = np.where(detour >= gate.reach_mm, 0.0, out)
    return np.asarray(gate.coupling + (1.0 - gate.coupling) * out, dtype=np.float64)


def _reference_linear_matrix(muscles: list[Any], rest: np.ndarray, gate: SlitGate | None) -> sp.csr_matrix:
    """MuscleField's W before the k-d tree: every vertex through each muscle's field, the gate's source the
    argmin over every vertex, the gates from `_reference_gate`."""
    vector = [m for m in muscles if not isinstance(m, EyelidMuscle)]
    rows, cols, vals = [], [], []
    for col, muscle in enumerate(vector):
        if isinstance(muscle, SphincterMuscle):
            continue
        idx, disp = muscle.unit_field(rest)
        if gate is not None and gate.has_slit and idx.size and gate.on_slit[idx].any():
            source = int(np.argmin(np.linalg.norm(rest - _insertion_mm(muscle), axis=1)))
            disp = disp * _reference_gate(gate, np.array([source]), idx)[:, None]
        rows.append((3 * idx[:, None] + np.arange(3)[None, :]).ravel())
        cols.append(np.full(3 * idx.size, col, dtype=np.int64))
        vals.append(disp.ravel())
    shape = (3 * rest.shape[0], len(vector))
    if not rows:
        return sp.csr_matrix(shape)
    w = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=shape)
    w.eliminate_zeros()
    return w


def _reference_bump(rest: np.ndarray, anchors: np.ndarray, radii: list[float], gate: SlitGate | None) -> Any:
    """AnchorFit's bump weights before the k-d tree: every vertex's distance to each anchor."""
    rows, cols, vals = [], [], []
    for a, (vertex, radius) in enumerate(zip(anchors, radii, strict=True)):
        d = np.linalg.norm(rest - rest[vertex], axis=1)
        idx = np.nonzero(d < radius)[0]
        weight = np.cos(d[idx] / radius * (math.pi / 2))
        if gate is not None and gate.has_slit and gate.on_slit[idx].any():
            weight = weight * _reference_gate(gate, np.array([int(vertex)]), idx)
        rows.append(idx)
        cols.append(np.full(idx.size, a))
        vals.append(weight)
    shape = (rest.shape[0], len(anchors))
    if not rows:
        return sp.csr_matrix(shape)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=shape)


def _same_csr(a: sp.csr_matrix, b: sp.csr_matrix) -> bool:
    a, b = sp.csr_matrix(a), sp.csr_matrix(b)
    return (
        a.shape == b.shape
        and np.array_equal(a.indptr, b.indptr)
        and np.array_equal(a.indices, b.indices)
        and np.array_equal(a.data, b.data)
    )


def _check_model(model: FaceModel) -> None:
    rest = np.asarray(model.head.skin.vertices_mm, dtype=np.float64)
    gate = model.field.slit
    if gate is not None:
        _, inverse, counts = np.unique(np.round(rest, 6), axis=0, return_inverse=True, return_counts=True)
        assert np.array_equal(gate.representative, inverse.ravel())
        assert np.array_equal(gate.on_slit, counts[inverse.ravel()] > 1)
    muscles = [
        as_model_muscle(m)
        for m in (model.head.muscles.values() if isinstance(model.head.muscles, dict) else model.head.muscles)
    ]
    assert _same_csr(model.field.linear_matrix, _reference_linear_matrix(muscles, rest, gate))
    anchors = np.array([a.vertex for a in model.anchor_actuators], dtype=np.int64)
    radii = [a.radius_mm for a in model.anchor_actuators]
    ref_bump = _reference_bump(rest, anchors, radii, gate)
    assert _same_csr(model.fit.bump, ref_bump)
    at_anchors = ref_bump[anchors].toarray() if anchors.size else np.zeros((0, 0))
    assert np.array_equal(model.fit.kernel, at_anchors * (model.fit.lines @ model.fit.lines.T))


# --- the heads -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("head_name", ["human", "dog"])
def test_the_built_in_heads_build_the_reference_model(head_name: str) -> None:
    _check_model(FaceModel(load_head(head_name)))


@pytest.fixture(scope="module")
def subdivided_human(tmp_path_factory: pytest.TempPathFactory) -> Any:
    from servoface.controller.benchmarks.scale import subdivided_profile

    folder: Path = tmp_path_factory.mktemp("scale")
    return load_head(subdivided_profile(1, folder / "human_sub1"))


def test_the_subdivided_human_builds_the_reference_model(subdivided_human: Any) -> None:
    assert len(subdivided_human.skin.vertices_mm) > 15000
    _check_model(FaceModel(subdivided_human))


def test_slit_gates_equal_the_whole_skin_search_on_random_sources(subdivided_human: Any) -> None:
    """Random sources near the mouth and random vertex sets around them, both sides of the slit."""
    rng = np.random.default_rng(17)
    rest = np.asarray(subdivided_human.skin.vertices_mm, dtype=np.float64)
    gate = SlitGate(rest, np.asarray(subdivided_human.skin.faces))
    assert gate.has_slit
    slit = np.nonzero(gate.on_slit)[0]
    centre = rest[slit].mean(axis=0)
    near_mouth = np.nonzero(np.linalg.norm(rest - centre, axis=1) < 40.0)[0]
    for trial in range(12):
        source = int(rng.choice(slit if trial % 3 == 0 else near_mouth))
        radius = float(rng.uniform(5.0, 60.0))
        around = np.nonzero(np.linalg.norm(rest - rest[source], axis=1) < radius)[0]
        idx = np.sort(rng.choice(around, size=max(1, around.size // 2), replace=False))
        got = gate._gate(np.array([source]), idx)
        want = _reference_gate(gate, np.array([source]), idx)
        assert np.array_equal(got, want), f"trial {trial}: source {source}, radius {radius:.1f}"


# --- the pieces on random inputs -------------------------------------------------------------------------


def test_row_groups_is_numpys_row_unique() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        base = np.round(rng.normal(size=(int(rng.integers(1, 40)), 3)), 1)
        base[rng.random(base.shape) < 0.2] = 0.0
        rows = base[rng.integers(0, base.shape[0], size=int(rng.integers(1, 200)))]
        rows[rng.random(rows.shape) < 0.1] *= -1.0  # -0.0 beside 0.0
        _, inverse, counts = np.unique(rows, axis=0, return_inverse=True, return_counts=True)
        got_inverse, got_counts = row_groups(rows)
        assert np.array_equal(got_inverse, inverse.ravel())
        assert np.array_equal(got_counts, counts)


def test_near_vertices_find_every_vertex_within_and_the_lowest_nearest() -> None:
    rng = np.random.default_rng(5)
    points = np.round(rng.uniform(-50.0, 50.0, size=(3000, 3)), 0)  # coarse: many ties and duplicates
    near = NearVertices(points)
    for _ in range(50):
        centre = np.round(rng.uniform(-60.0, 60.0, size=3), 0)
        radius = float(rng.choice([0.0, 1.0, float(rng.uniform(0.0, 40.0)), 5.0]))
        cand = near.within(centre, radius)
        d = np.linalg.norm(points - centre, axis=1)
        assert np.array_equal(cand[d[cand] <= radius], np.nonzero(d <= radius)[0])
        assert np.all(np.diff(cand) > 0)
        assert near.nearest(centre) == int(np.argmin(d))


def test_linear_fields_from_the_tree_equal_the_whole_skin_fields() -> None:
    rng = np.random.default_rng(11)
    from servoface.sim.muscles.linear import LinearMuscle

    rest = rng.uniform(-40.0, 40.0, size=(4000, 3))
    muscles = [
        LinearMuscle(
            f"m{k}",
            tuple(rng.uniform(-30.0, 30.0, size=3)),
            tuple(rng.uniform(-30.0, 30.0, size=3)),
            zone_deg=float(rng.uniform(10.0, 90.0)),
        )
        for k in range(8)
    ]
    field = MuscleField(muscles, rest)
    assert _same_csr(field.linear_matrix, _reference_linear_matrix(list(muscles), rest, None))


def test_forgetting_the_shared_gates_makes_the_next_build_cold() -> None:
    """`bench scale` times a cold build: after ``forget_shared_gates`` the same mesh gets a new gate."""
    head = load_head("human")
    rest, faces = head.skin.vertices_mm, head.skin.faces
    first = slit_gate(rest, faces)
    assert slit_gate(rest, faces) is first  # shared while remembered
    forget_shared_gates()
    again = slit_gate(rest, faces)
    assert again is not first
    assert np.array_equal(again.representative, first.representative)
