"""Waters-style muscle formulas against hand-computed values (muscle-models.md §1, corrected forms)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.sim.muscles.eyelid import EyelidMuscle
from servoface.sim.muscles.field import MuscleField
from servoface.sim.muscles.linear import LinearMuscle, angular_factor, radial_factor
from servoface.sim.muscles.sheet import SheetMuscle, band_factor, parallel_factor
from servoface.sim.muscles.sphincter import SphincterMuscle, sphincter_falloff

S = math.sqrt(0.5)  # cos 45° = 0.70710678...

# --- linear -------------------------------------------------------------------------------------------


def test_radial_factor_spot_values_of_the_sheet() -> None:
    # muscle-models.md §1.1: I = 1, D = 2: |v| = 0, 0.5, 1, 1.5, 2 -> 0, 0.707, 1, 0.707, 0
    got = radial_factor(np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5]), 1.0, 2.0)
    assert got == pytest.approx([0.0, S, 1.0, S, 0.0, 0.0], abs=1e-12)


def test_angular_factor_is_one_on_the_axis_and_zero_at_the_edge() -> None:
    zone = math.radians(45.0)
    got = angular_factor(np.array([0.0, zone / 2, zone, zone * 1.2]), zone)
    assert got == pytest.approx([1.0, S, 0.0, 0.0], abs=1e-12)


def _linear() -> LinearMuscle:
    # ap = origin, ip = (10, 0, 0): I = 10, rs = 10, rf = 20, θ = 45°, λ = 0.25 -> k = 2.5 mm
    return LinearMuscle("m", (0.0, 0.0, 0.0), (10.0, 0.0, 0.0), 45.0, 10.0, 20.0, 0.25)


def _field_at(muscle: LinearMuscle | SheetMuscle, points: list[tuple[float, float, float]]) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    idx, disp = muscle.unit_field(pts)
    out = np.zeros_like(pts)
    out[idx] = disp
    return out


def test_linear_hand_computed_displacements() -> None:
    d22 = math.radians(22.5)
    pts = [
        (0.0, 0.0, 0.0),  # the attachment never moves
        (5.0, 0.0, 0.0),  # r = cos(π/4), a = 1 -> 2.5 · 0.7071 towards ap
        (10.0, 0.0, 0.0),  # insertion: r = a = 1 -> 2.5
        (15.0, 0.0, 0.0),  # r = cos(π/4)
        (20.0, 0.0, 0.0),  # rf: 0
        (25.0, 0.0, 0.0),  # outside
        (10 * math.cos(d22), 10 * math.sin(d22), 0.0),  # half the zone: a = cos(π/4)
        (10 * math.cos(math.radians(45)), 0.0, 10 * math.sin(math.radians(45))),  # zone edge: 0
        (-10.0, 0.0, 0.0),  # behind the attachment
    ]
    got = _field_at(_linear(), pts)
    k = 2.5
    assert got[0] == pytest.approx([0, 0, 0])
    assert got[1] == pytest.approx([-k * S, 0, 0])
    assert got[2] == pytest.approx([-k, 0, 0])
    assert got[3] == pytest.approx([-k * S, 0, 0])
    assert got[4] == pytest.approx([0, 0, 0], abs=1e-12)
    assert got[5] == pytest.approx([0, 0, 0])
    assert got[6] == pytest.approx([-k * S * math.cos(d22), -k * S * math.sin(d22), 0.0])
    assert got[7] == pytest.approx([0, 0, 0], abs=1e-12)
    assert got[8] == pytest.approx([0, 0, 0])


def test_linear_pulls_towards_the_attachment() -> None:
    rng = np.random.default_rng(1)
    pts = rng.uniform(-25, 25, size=(4000, 3))
    idx, disp = _linear().unit_field(pts)
    assert idx.size > 100
    towards = -pts[idx] / np.linalg.norm(pts[idx], axis=1)[:, None]  # unit vector to ap (origin)
    cos = np.einsum("ij,ij->i", disp, towards) / np.linalg.norm(disp, axis=1)
    assert cos == pytest.approx(np.ones_like(cos))
    # never past the attachment
    assert np.all(np.linalg.norm(disp, axis=1) < np.linalg.norm(pts[idx], axis=1))


@settings(max_examples=60, deadline=None)
@given(
    d=st.floats(0.0, 20.0),
    phi=st.floats(0.0, math.radians(44.9)),
    eps=st.floats(1e-6, 1e-2),
)
def test_linear_field_is_continuous(d: float, phi: float, eps: float) -> None:
    """A small step in distance or angle moves the displacement at most by a Lipschitz bound."""
    m = _linear()

    def at(dist: float, ang: float) -> np.ndarray:
        return _field_at(m, [(dist * math.cos(ang), dist * math.sin(ang), 0.0)])[0]

    bound = m.gain_mm * (math.pi / 2) * eps * (1 / min(m.rs_mm, m.rf_mm - m.rs_mm) + 1)
    assert np.linalg.norm(at(d + eps, phi) - at(d, phi)) <= bound + 1e-9
    zone = math.radians(m.zone_deg)
    angle_bound = m.gain_mm * ((math.pi / 2) / zone + 1) * eps
    assert np.linalg.norm(at(d, min(phi + eps, zone)) - at(d, phi)) <= angle_bound + 1e-9


def test_linear_field_vanishes_continuously_at_both_zone_edges() -> None:
    m = _linear()
    zone = math.radians(45.0)
    near_edge = [(10 * math.cos(zone - 1e-6), 10 * math.sin(zone - 1e-6), 0.0)]
    assert np.linalg.norm(_field_at(m, near_edge)) < 1e-5
    assert np.linalg.norm(_field_at(m, [(20.0 - 1e-6, 0.0, 0.0)])) < 1e-5
    assert np.linalg.norm(_field_at(m, [(1e-6, 0.0, 0.0)])) < 1e-5


# --- sheet --------------------------------------------------------------------------------------------


def test_parallel_factor_is_continuous_at_the_insertion() -> None:
    # corrected outer falloff joins the inner one at I for any D_par (printed form drops to 0.866)
    for reach in (1.5, 2.0, 3.0):
        left = parallel_factor(1.0 - 1e-9, 1.0, reach)
        right = parallel_factor(1.0 + 1e-9, 1.0, reach)
        assert float(left) == pytest.approx(1.0, abs=1e-6) and float(right) == pytest.approx(1.0, abs=1e-6)
    assert parallel_factor(np.array([-0.5, 0.0, 0.5, 1.0, 2.0, 3.0, 3.5]), 1.0, 3.0) == pytest.approx(
        [0.0, 0.0, S, 1.0, S, 0.0, 0.0], abs=1e-12
    )
    assert band_factor(np.array([-3.0, 0.0, 2.5, 5.0, 6.0]), 5.0) == pytest.approx([1, 1, S, 0, 0], abs=1e-12)


def _sheet() -> SheetMuscle:
    # attachment line y = 0 from x = 0..20, insertion line y = 10: fibres along +y, I = 10, k = 2.5,
    # side band 5 mm, parallel falloff 5 mm past the insertion, depth band 5 mm (defaults = I/2)
    return SheetMuscle("s", (0.0, 0.0, 0.0), (20.0, 0.0, 0.0), (0.0, 10.0, 0.0), (20.0, 10.0, 0.0), 5.0, 0.25)


def test_sheet_hand_computed_displacements() -> None:
    got = _field_at(
        _sheet(),
        [
            (10.0, 10.0, 0.0),  # insertion line: 2.5 towards the attachment line (-y)
            (10.0, 5.0, 0.0),  # a_par = sin(π/4)
            (10.0, 12.5, 0.0),  # outer falloff cos(π/4)
            (10.0, 15.0, 0.0),  # D_par: 0
            (22.5, 10.0, 0.0),  # half the side band: cos(π/4)
            (10.0, 0.0, 0.0),  # on the attachment line: 0
            (10.0, -1.0, 0.0),  # behind it: 0 (signed projection)
            (10.0, 10.0, 7.5),  # half the depth band: cos(π/4)
            (10.0, 10.0, -20.0),  # far behind the sheet: 0
        ],
    )
    k = 2.5
    expected = [
        [0, -k, 0],
        [0, -k * S, 0],
        [0, -k * S, 0],
        [0, 0, 0],
        [0, -k * S, 0],
        [0, 0, 0],
        [0, 0, 0],
        [0, -k * S, 0],
        [0, 0, 0],
    ]
    assert got == pytest.approx(np.array(expected, dtype=float), abs=1e-9)


def test_sheet_moves_every_point_along_its_fibres() -> None:
    rng = np.random.default_rng(2)
    pts = rng.uniform([-10, -5, -10], [30, 20, 10], size=(3000, 3))
    idx, disp = _sheet().unit_field(pts)
    assert idx.size > 200
    assert np.allclose(disp[:, [0, 2]], 0.0)
    assert np.all(disp[:, 1] < 0.0)


def test_fanned_sheet_follows_each_fibre() -> None:
    fan = SheetMuscle("f", (0.0, 0.0, 0.0), (20.0, 0.0, 0.0), (-5.0, 10.0, 0.0), (25.0, 10.0, 0.0), 5.0, 0.25)
    got = _field_at(fan, [(-5.0, 10.0, 0.0), (25.0, 10.0, 0.0)])
    fibre_left = np.array([-5.0, 10.0, 0.0]) / math.hypot(5, 10)
    fibre_right = np.array([5.0, 10.0, 0.0]) / math.hypot(5, 10)
    k = 0.25 * math.hypot(5, 10)
    assert got[0] == pytest.approx(-k * fibre_left)
    assert got[1] == pytest.approx(-k * fibre_right)


# --- sphincter ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("s_maj", "s_min", "printed", "corrected"),
    [(0, 0, 1.0, 1.0), (2, 0, -1.0, 0.0), (0, 1, 0.5, 0.0), (1, 0.5, -0.031, 0.293)],
)
def test_sphincter_check_values_of_the_sheet(s_maj: float, s_min: float, printed: float, corrected: float) -> None:
    assert float(sphincter_falloff(s_maj, s_min, 2.0, 1.0, "printed")) == pytest.approx(printed, abs=1e-3)
    assert float(sphincter_falloff(s_maj, s_min, 2.0, 1.0)) == pytest.approx(corrected, abs=1e-3)


def test_sphincter_forms_agree_on_a_circle() -> None:
    a = np.linspace(0, 1, 11)
    assert sphincter_falloff(a * 0.6, a * 0.8, 1.0, 1.0, "printed") == pytest.approx(
        sphincter_falloff(a * 0.6, a * 0.8, 1.0, 1.0)
    )


def _ring() -> SphincterMuscle:
    # centre at origin, semi-axes 20 (x) x 10 (y), depth 20; λ = 0.25 -> k = 5 mm
    return SphincterMuscle("o", (0.0, 0.0, 0.0), (20.0, 10.0, 20.0), 0.25)


def test_sphincter_hand_computed_displacements() -> None:
    pts = np.array([[10.0, 0, 0], [0, 5.0, 0], [1.0, 0, 0], [20.0, 0, 0], [0, 0, 0], [30.0, 0, 0]])
    field = _ring().field(pts)
    out = np.zeros_like(pts)
    out[field.index] = field.displacement(1.0)
    assert out[0] == pytest.approx([-2.5, 0, 0])  # ρ = 0.5: g = 0.5, k·g = 2.5 towards the centre
    assert out[1] == pytest.approx([0, -2.5, 0])
    assert out[2] == pytest.approx([-1.0, 0, 0])  # k·g = 4.75 > 1: capped, lands on the centre, not past
    assert out[3] == pytest.approx([0, 0, 0])  # on the ellipse
    assert out[4] == pytest.approx([0, 0, 0])  # the centre
    assert out[5] == pytest.approx([0, 0, 0])  # outside
    # half the contraction: half the pull (below the cap), and the counter pushes out
    out_half = np.zeros_like(pts)
    out_half[field.index] = field.displacement(0.5)
    assert out_half[0] == pytest.approx([-1.25, 0, 0])
    out_neg = np.zeros_like(pts)
    out_neg[field.index] = field.displacement(-0.2)
    assert out_neg[0] == pytest.approx([0.5, 0, 0])


def test_sphincter_pulls_towards_its_centre_and_never_past_it() -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform(-25, 25, size=(4000, 3))
    pts[:, 2] *= 0.3
    field = _ring().field(pts)
    disp = field.displacement(1.0)
    planar = pts[field.index].copy()
    planar[:, 2] = 0.0
    assert np.all(np.einsum("ij,ij->i", disp, planar) < 0)
    assert np.allclose(disp[:, 2], 0.0)
    assert np.all(np.linalg.norm(disp, axis=1) <= np.linalg.norm(planar, axis=1) + 1e-12)


# --- eyelid -------------------------------------------------------------------------------------------


def test_eyelid_turns_the_margin_down_and_keeps_points_outside_the_eyeball() -> None:
    lid = EyelidMuscle("lid", (0.0, 0.0, 0.0), 10.0, "upper_lid_l", thickness_mm=1.0, reach_mm=16.0)
    up30 = math.radians(30)
    margin = np.array([[0.0, 11 * math.sin(up30), 11 * math.cos(up30)]])  # on the shell, 30° above forward
    field = lid.field(margin)
    moved = margin[field.index] + field.displacement(30.0)
    assert moved[0] == pytest.approx([0.0, 0.0, 11.0], abs=1e-9)  # turned down onto the forward axis
    rng = np.random.default_rng(4)
    pts = rng.normal(size=(2000, 3))
    pts = pts / np.linalg.norm(pts, axis=1)[:, None] * rng.uniform(11.0, 18.0, size=(2000, 1))
    field = lid.field(pts)
    assert field.index.size > 100
    for angle in (10.0, 40.0, 55.0, -15.0):
        moved = pts[field.index] + field.displacement(angle)
        assert np.all(np.linalg.norm(moved, axis=1) >= 11.0 - 1e-9)
    lower = EyelidMuscle("low", (0.0, 0.0, 0.0), 10.0, "lower_lid_l", part="lower")
    below = np.array([[0.0, -11 * math.sin(up30), 11 * math.cos(up30)]])
    lf = lower.field(below)
    assert (below[lf.index] + lf.displacement(30.0))[0] == pytest.approx([0, 0, 11.0], abs=1e-9)  # + raises


# --- the combined field -------------------------------------------------------------------------------


def _grid() -> np.ndarray:
    g = np.stack(np.meshgrid(np.linspace(-30, 30, 31), np.linspace(-30, 30, 31)), -1).reshape(-1, 2)
    return np.c_[g, np.zeros(len(g))]


def test_field_is_order_independent_and_sums_single_muscles() -> None:
    rest = _grid()
    muscles = [
        LinearMuscle("a", (-20.0, 0, -2), (0.0, 5, 0), 40, 20, 30, 0.25),
        SheetMuscle("b", (-10.0, 25, -1), (10.0, 25, -1), (-10.0, 10, 0), (10.0, 10, 0), 5.0, 0.25),
        SphincterMuscle("c", (0.0, -10, 0), (15.0, 8.0, 10.0), 0.25),
    ]
    c = np.array([0.3, 0.7, 0.5])
    forward = MuscleField(muscles, rest)
    backward = MuscleField(muscles[::-1], rest)
    a = forward.offsets(c)
    b = backward.offsets(c[::-1])
    assert np.abs(a).max() > 1.0
    assert np.allclose(a, b)
    singles = sum(MuscleField([m], rest).offsets(np.array([ci])) for m, ci in zip(muscles, c, strict=True))
    assert np.allclose(a, singles)


@settings(max_examples=40, deadline=None)
@given(c1=st.floats(0.0, 1.0), c2=st.floats(0.0, 1.0), t=st.floats(0.0, 1.0))
def test_linear_and_sheet_fields_are_linear_in_contraction(c1: float, c2: float, t: float) -> None:
    rest = _grid()
    field = MuscleField(
        [
            LinearMuscle("a", (-20.0, 0, -2), (0.0, 5, 0), 40, 20, 30, 0.25),
            SheetMuscle("b", (-10.0, 25, -1), (10.0, 25, -1), (-10.0, 10, 0), (10.0, 10, 0), 5.0, 0.25),
        ],
        rest,
    )
    x, y = np.array([c1, c2]), np.array([c2, c1])
    mix = field.offsets(t * x + (1 - t) * y)
    assert np.allclose(mix, t * field.offsets(x) + (1 - t) * field.offsets(y), atol=1e-9)
    assert np.allclose(field.offsets(np.zeros(2)), 0.0)


def test_field_turns_eyelid_regions_with_their_joint_only() -> None:
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(500, 3))
    pts = pts / np.linalg.norm(pts, axis=1)[:, None] * rng.uniform(11.0, 15.0, size=(500, 1))
    lid = EyelidMuscle("lid_l", (0.0, 0.0, 0.0), 10.0, "upper_lid_l")
    field = MuscleField([_ring(), lid], pts)
    assert field.names == ("o",)  # eyelids are driven by joints, not contractions
    still = field.offsets(np.zeros(1), {"upper_lid_r": 30.0})
    moved = field.offsets(np.zeros(1), {"upper_lid_l": 30.0})
    assert np.allclose(still, 0.0)
    assert np.abs(moved).max() > 1.0
    assert np.all(moved[pts[:, 1] < 0] == 0.0)  # only the upper region turns
