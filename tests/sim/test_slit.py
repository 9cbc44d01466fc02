"""The slit gate (sim/muscles/slit.py): a field reaches the far side of a slit only round its ends."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.heads import mesh_tools as mt
from servoface.sim.muscles.field import MuscleField
from servoface.sim.muscles.linear import LinearMuscle
from servoface.sim.muscles.slit import SLIT_COUPLING, SlitGate, slit_gate


def _slit_grid(step_mm: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A flat 41 x 21 grid (x -40..40, y -20..20 mm) cut along y = 0 for |x| < 20 (a mouth)."""
    xs = np.arange(-40.0, 40.0 + 1e-9, step_mm)
    ys = np.arange(-20.0, 20.0 + 1e-9, step_mm)
    gx, gy = np.meshgrid(xs, ys)
    verts = np.c_[gx.ravel(), gy.ravel(), np.zeros(gx.size)]
    faces = mt.grid_faces(ys.size, xs.size, periodic_u=False)
    row = int(np.argmin(np.abs(ys)))
    slit = row * xs.size + np.nonzero(np.abs(xs) < 20.0)[0]
    below = np.all(verts[faces][:, :, 1] <= 1e-9, axis=1) & np.isin(faces, slit).any(axis=1)
    verts, faces, _ = mt.split_vertices(verts, faces, slit, below)
    return verts, faces


def _nearest(verts: np.ndarray, x: float, y: float) -> int:
    return int(np.argmin(np.linalg.norm(verts[:, :2] - (x, y), axis=1)))


def test_the_far_lip_gets_only_the_coupling_share_and_the_corners_stay_whole() -> None:
    verts, faces = _slit_grid()
    gate = SlitGate(verts, faces)
    source = _nearest(verts, 0.0, 6.0)  # on the upper lip
    g = gate.gate(source)
    assert g[_nearest(verts, 0.0, 4.0)] == pytest.approx(1.0)  # own lip
    assert g[_nearest(verts, 0.0, -4.0)] == pytest.approx(SLIT_COUPLING)  # far lip, mid-mouth
    assert g[_nearest(verts, 30.0, -4.0)] == pytest.approx(1.0)  # beyond the corner: no detour
    assert np.all((g >= SLIT_COUPLING - 1e-12) & (g <= 1.0 + 1e-12))


def test_a_source_on_the_slit_is_on_both_sides() -> None:
    verts, faces = _slit_grid()
    on = np.nonzero(np.isclose(verts[:, 1], 0.0) & (np.abs(verts[:, 0]) < 1e-9))[0]
    assert on.size == 2
    assert np.allclose(SlitGate(verts, faces).gate(int(on[0])), 1.0)


def test_a_skin_without_a_slit_gates_nothing_and_the_gate_is_shared() -> None:
    xs = np.arange(0.0, 10.0, 1.0)
    gx, gy = np.meshgrid(xs, xs)
    verts = np.c_[gx.ravel(), gy.ravel(), np.zeros(gx.size)]
    faces = mt.grid_faces(10, 10, periodic_u=False)
    gate = SlitGate(verts, faces)
    assert not gate.has_slit and np.all(gate.gate(0) == 1.0)
    assert slit_gate(verts, faces) is slit_gate(verts.copy(), faces.copy())


def test_a_lip_muscle_moves_its_own_lip_and_the_field_is_unchanged_without_faces() -> None:
    verts, faces = _slit_grid()
    muscle = LinearMuscle("levator", (0.0, 30.0, -5.0), (0.0, 4.0, 0.0), 40.0, 30.0, 45.0, 0.25)
    gated = MuscleField([muscle], verts, faces).offsets(np.array([1.0]))
    plain = MuscleField([muscle], verts).offsets(np.array([1.0]))
    up, lo = (int(i) for i in np.nonzero(np.isclose(verts[:, 1], 0.0) & np.isclose(verts[:, 0], 0.0))[0])
    assert np.allclose(plain[up], plain[lo])  # the old behaviour: both lips alike
    assert np.linalg.norm(gated[up] - gated[lo]) > 0.3 * np.linalg.norm(plain[up])  # the lips part
