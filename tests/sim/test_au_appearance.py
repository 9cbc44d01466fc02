"""Each AU's appearance change, as FACS / DFACS describes it, on the ACHIEVABLE face of both built-in heads.

The achievable face is what the twin shows for the servos' goals: the muscle model's actuator targets ->
the built-in calibration (integer goal ticks and back) -> ``FaceModel.pose_from_targets``
(``servoface.sim.landmarks.achievable_pose``). Landmarks: ``servoface.sim.landmarks.landmark_set``.
Magnitudes are fractions of the head's size D = the distance between its eye centres (human 64 mm, dog
54 mm), sized so the change is visible at 2 m (one arc minute there is 0.6 mm); each threshold sits
below what the head does now, so a regression that hides the AU fails. The direction conventions are the
head frame's: +x the head's own left, +y up, +z out of the face (along the muzzle for the dog).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache

import numpy as np
import pytest
from numpy.typing import NDArray
from servoface.calibration import load_calibration
from servoface.sim.expressions import load_library
from servoface.sim.face_model import FaceModel
from servoface.sim.heads import load_head
from servoface.sim.kinematics import posed_skin_vertices
from servoface.sim.landmarks import achievable_pose, landmark_set

X, Y, Z = 0, 1, 2


class Face:
    """A built-in head's achievable face, landmark by landmark, relative to its neutral face."""

    def __init__(self, name: str) -> None:
        self.head = load_head(name)
        self.model = FaceModel(self.head)
        self.calibration = load_calibration(self.head.calibration_path)
        self.landmarks = landmark_set(self.head)
        lm = self.head.landmarks_mm
        self.size_mm = float(np.linalg.norm(np.subtract(lm["eye_centre_l"], lm["eye_centre_r"])))
        self.rest = self.at({})

    def at(self, aus: Mapping[str, float]) -> dict[str, NDArray[np.float64]]:
        pose = achievable_pose(self.model, self.calibration, self.model.solve(aus))
        return dict(zip(self.landmarks.names, self.landmarks.positions(pose), strict=True))

    def moved(self, aus: Mapping[str, float]) -> dict[str, NDArray[np.float64]]:
        """landmark -> displacement (mm) from neutral on the achievable face."""
        return {k: v - self.rest[k] for k, v in self.at(aus).items()}

    def skin(self, aus: Mapping[str, float]) -> NDArray[np.float64]:
        """(n, 3) posed skin vertices (mm) of the achievable face."""
        pose = achievable_pose(self.model, self.calibration, self.model.solve(aus))
        return posed_skin_vertices(self.head, pose)

    def lip_pair(self, near_mm: tuple[float, float, float]) -> tuple[int, int]:
        """The two copies (upper lip, lower lip) of the mouth-slit vertex nearest ``near_mm``: they share a
        rest position; the upper copy belongs to faces above the slit."""
        rest = np.asarray(self.head.skin.vertices_mm, dtype=np.float64)
        faces = np.asarray(self.head.skin.faces)
        _, inverse, counts = np.unique(np.round(rest, 6), axis=0, return_inverse=True, return_counts=True)
        on = np.nonzero((counts[inverse.ravel()] == 2) & (rest[:, Z] > 40.0))[0]
        v = int(on[np.argmin(np.linalg.norm(rest[on] - np.asarray(near_mm), axis=1))])
        pair = np.nonzero(np.all(np.isclose(rest, rest[v], atol=1e-6), axis=1))[0]
        above = [int(i) for i in pair if rest[faces[np.any(faces == i, axis=1)]][:, :, Y].mean() > rest[i, Y]]
        below = [int(i) for i in pair if int(i) not in above]
        return above[0], below[0]

    def lip_gap_mm(self, aus: Mapping[str, float], near_mm: tuple[float, float, float]) -> float:
        """How far the lips part (mm, upper minus lower lip edge, vertically) at the slit point near ``near_mm``."""
        up, lo = self.lip_pair(near_mm)
        v = self.skin(aus)
        return float(v[up, Y] - v[lo, Y])

    def d(self, fraction: float) -> float:
        """``fraction`` of the head's size, in mm."""
        return fraction * self.size_mm

    def expression(self, name: str) -> dict[str, float]:
        return dict(load_library(self.head.face_type)[name].apex())


@cache
def _face(name: str) -> Face:
    return Face(name)


@pytest.fixture(scope="module")
def human() -> Face:
    return _face("human")


@pytest.fixture(scope="module")
def dog() -> Face:
    return _face("dog")


def _gap(p: Mapping[str, NDArray[np.float64]], a: str, b: str, axis: int = X) -> float:
    return float(abs(p[a][axis] - p[b][axis]))


# --- human: FACS (facs-human.md §1; Ekman, Friesen & Hager, FACS Manual 2002) ---------------------------


def test_au1_raises_the_inner_brows(human: Face) -> None:
    """FACS AU1 Inner Brow Raiser (frontalis, pars medialis): the inner corners of the brows are pulled up;
    the outer brow stays (facs-human.md §1)."""
    d = human.moved({"AU1": 1.0})
    for side in "lr":
        assert d[f"anchor_brow_inner_{side}"][Y] >= human.d(0.08)
        assert abs(d[f"anchor_brow_outer_{side}"][Y]) <= 0.3 * d[f"anchor_brow_inner_{side}"][Y]


def test_au2_raises_the_outer_brows(human: Face) -> None:
    """FACS AU2 Outer Brow Raiser (frontalis, pars lateralis): the lateral part of the brows goes up
    (facs-human.md §1)."""
    d = human.moved({"AU2": 1.0})
    for side in "lr":
        assert d[f"anchor_brow_outer_{side}"][Y] >= human.d(0.08)
        assert abs(d[f"anchor_brow_inner_{side}"][Y]) <= 0.3 * d[f"anchor_brow_outer_{side}"][Y]


def test_au4_lowers_the_brows_and_draws_them_together(human: Face) -> None:
    """FACS AU4 Brow Lowerer (corrugator supercilii, depressor supercilii, procerus): the brows are lowered
    and drawn together, a V with vertical creases between them (facs-human.md §1: 'brow down and in')."""
    rest, p = human.rest, human.at({"AU4": 1.0})
    d = human.moved({"AU4": 1.0})
    for side in "lr":
        assert d[f"anchor_brow_inner_{side}"][Y] <= -human.d(0.035)
    together = _gap(rest, "anchor_brow_inner_l", "anchor_brow_inner_r") - _gap(
        p, "anchor_brow_inner_l", "anchor_brow_inner_r"
    )
    assert together >= human.d(0.05)
    knit = _gap(rest, "anchor_brow_knit_l", "anchor_brow_knit_r") - _gap(p, "anchor_brow_knit_l", "anchor_brow_knit_r")
    assert knit >= human.d(0.1)


def test_au4_lowers_the_outer_brow_too_but_less_than_the_inner(human: Face) -> None:
    """FACS AU4 lowers the brow along its length, the inner part most (corrugator, procerus); the lateral
    part comes down with the superolateral orbicularis oculi (FACS Manual 2002, AU4). Before issue 11's
    brow depressor no muscle lowered the outer brow: its anchor stayed at 0.0 mm."""
    d = human.moved({"AU4": 1.0})
    for side in "lr":
        outer, inner = d[f"anchor_brow_outer_{side}"][Y], d[f"anchor_brow_inner_{side}"][Y]
        assert outer <= -human.d(0.02)  # 1.3 mm; measured 1.8 mm
        assert inner < outer  # the inner brow lower: the V stays


def test_au1_with_au4_raises_the_inner_brows_while_drawing_them_together(human: Face) -> None:
    """FACS AU1+4 (the sadness brow; FACS Manual, AU1+4 combination): the inner brows go up and come
    together -- they do not move apart (facs-human.md §2a sadness 1 + 4 + 15)."""
    rest, p = human.rest, human.at({"AU1": 1.0, "AU4": 1.0})
    d = human.moved({"AU1": 1.0, "AU4": 1.0})
    for side in "lr":
        assert d[f"anchor_brow_inner_{side}"][Y] >= human.d(0.04)
    together = _gap(rest, "anchor_brow_inner_l", "anchor_brow_inner_r") - _gap(
        p, "anchor_brow_inner_l", "anchor_brow_inner_r"
    )
    assert together >= human.d(0.05)


def test_au5_raises_the_upper_lid_so_sclera_shows_above_the_iris(human: Face) -> None:
    """FACS AU5 Upper Lid Raiser (levator palpebrae superioris): the upper lid goes up, exposing the
    sclera above the iris (facs-human.md §1)."""
    iris = next(p for p in human.head.parts if p.name == "iris_l")
    iris_top_y = float(np.asarray(iris.mesh.vertices)[:, Y].max())
    assert human.rest["margin_upper_lid_l"][Y] < iris_top_y  # at rest the lid covers the iris top
    for side in "lr":
        p = human.at({"AU5": 1.0})
        assert p[f"margin_upper_lid_{side}"][Y] - iris_top_y >= human.d(0.02)
        assert human.moved({"AU5": 1.0})[f"margin_upper_lid_{side}"][Y] >= human.d(0.04)


def test_au6_raises_the_cheek_and_lower_lid(human: Face) -> None:
    """FACS AU6 Cheek Raiser (orbicularis oculi, pars orbitalis): the cheek is lifted and the skin below
    the eye bunches, the lower lid rises (facs-human.md §1)."""
    d = human.moved({"AU6": 1.0})
    for side in "lr":
        assert d[f"anchor_cheek_{side}"][Y] >= human.d(0.02)
        assert d[f"margin_lower_lid_{side}"][Y] >= human.d(0.03)


def test_au7_tightens_the_lids(human: Face) -> None:
    """FACS AU7 Lid Tightener (orbicularis oculi, pars palpebralis): the lower lid rises and straightens,
    the eye opening narrows (facs-human.md §1)."""
    rest, p = human.rest, human.at({"AU7": 1.0})
    for side in "lr":
        assert p[f"margin_lower_lid_{side}"][Y] - rest[f"margin_lower_lid_{side}"][Y] >= human.d(0.05)
        aperture_rest = _gap(rest, f"margin_upper_lid_{side}", f"margin_lower_lid_{side}", Y)
        aperture = _gap(p, f"margin_upper_lid_{side}", f"margin_lower_lid_{side}", Y)
        assert aperture <= 0.5 * aperture_rest


def test_au9_wrinkles_the_nose_and_lifts_the_upper_lip(human: Face) -> None:
    """FACS AU9 Nose Wrinkler (levator labii superioris alaeque nasi): the skin of the nose wings is pulled
    up, wrinkling the nose, and the upper lip is raised (facs-human.md §1)."""
    d = human.moved({"AU9": 1.0})
    for side in "lr":
        assert d[f"nose_wing_{side}"][Y] >= human.d(0.02)
    assert d["anchor_upper_lip"][Y] >= human.d(0.035)


def test_au10_raises_the_upper_lip_into_an_arch(human: Face) -> None:
    """FACS AU10 Upper Lip Raiser (levator labii superioris): the upper lip is drawn up, its middle and
    sides more than the corners, an inverted U (facs-human.md §1)."""
    d = human.moved({"AU10": 1.0})
    assert d["anchor_upper_lip"][Y] >= human.d(0.06)
    for side in "lr":
        assert d[f"upper_lip_{side}"][Y] >= human.d(0.1)
        assert d[f"upper_lip_{side}"][Y] >= 2.0 * d[f"mouth_corner_{side}"][Y]
    assert abs(d["anchor_lower_lip"][Y]) <= human.d(0.01)  # the lower lip stays


@pytest.mark.parametrize("x_mm", [-12.0, 12.0])
def test_au10_alone_parts_the_lips(human: Face, x_mm: float) -> None:
    """FACS AU10 (levator labii superioris): 'with strong action the lips part' -- the upper lip rises away
    from the lower one, which stays (FACS Manual 2002, AU10; facs-human.md §1). The muscle fields are gated
    across the mouth slit (sim/muscles/slit.py): before, both lips moved together and the gap was 0."""
    near = (x_mm, 72.0, 88.0)
    assert abs(human.lip_gap_mm({}, near)) <= 1e-6  # closed at rest
    gap = human.lip_gap_mm({"AU10": 1.0}, near)
    assert gap >= human.d(0.05)  # 3.2 mm; measured 4.2 mm
    up, lo = human.lip_pair(near)
    moved = human.skin({"AU10": 1.0}) - human.skin({})
    assert moved[up, Y] >= 2.5 * moved[lo, Y]  # the upper lip leads; the lower follows only a little


def test_au16_parts_the_lips_downwards(human: Face) -> None:
    """FACS AU16 Lower Lip Depressor (depressor labii inferioris): the lower lip is pulled down away from
    the upper lip, which stays (facs-human.md §1)."""
    gap = human.lip_gap_mm({"AU16": 1.0}, (12.0, 72.0, 88.0))
    assert gap >= human.d(0.04)  # 2.6 mm; measured 3.5 mm
    up, lo = human.lip_pair((12.0, 72.0, 88.0))
    moved = human.skin({"AU16": 1.0}) - human.skin({})
    assert -moved[lo, Y] >= 2.5 * abs(moved[up, Y])


def test_au12_pulls_the_lip_corners_up_and_out(human: Face) -> None:
    """FACS AU12 Lip Corner Puller (zygomaticus major): the corners are pulled obliquely up and back
    (facs-human.md §1)."""
    d = human.moved({"AU12": 1.0})
    assert d["mouth_corner_l"][Y] >= human.d(0.08) and d["mouth_corner_r"][Y] >= human.d(0.08)
    assert d["mouth_corner_l"][X] >= human.d(0.08) and d["mouth_corner_r"][X] <= -human.d(0.08)


def test_au14_pulls_the_corners_back_not_up(human: Face) -> None:
    """FACS AU14 Dimpler (buccinator): the lip corners are drawn back and tightened, without rising
    (facs-human.md §1)."""
    d = human.moved({"AU14": 1.0})
    for side in "lr":
        assert d[f"mouth_corner_{side}"][Z] <= -human.d(0.04)
        assert abs(d[f"mouth_corner_{side}"][Y]) <= human.d(0.01)


def test_au15_pulls_the_corners_down(human: Face) -> None:
    """FACS AU15 Lip Corner Depressor (depressor anguli oris / triangularis): the corners are pulled down
    (facs-human.md §1)."""
    d = human.moved({"AU15": 1.0})
    for side in "lr":
        assert d[f"mouth_corner_{side}"][Y] <= -human.d(0.06)


def test_au16_pulls_the_lower_lip_down(human: Face) -> None:
    """FACS AU16 Lower Lip Depressor (depressor labii inferioris): the lower lip is pulled down
    (facs-human.md §1)."""
    d = human.moved({"AU16": 1.0})
    assert d["anchor_lower_lip"][Y] <= -human.d(0.03)


def test_au17_pushes_the_chin_up(human: Face) -> None:
    """FACS AU17 Chin Raiser (mentalis): the chin boss and the lower lip are pushed up (facs-human.md §1)."""
    d = human.moved({"AU17": 1.0})
    assert d["anchor_chin"][Y] >= human.d(0.05)


def test_au20_stretches_the_lips_sideways(human: Face) -> None:
    """FACS AU20 Lip Stretcher (risorius + platysma): the corners are pulled laterally, the mouth widens
    and flattens (facs-human.md §1)."""
    rest, p = human.rest, human.at({"AU20": 1.0})
    wider = _gap(p, "mouth_corner_l", "mouth_corner_r") - _gap(rest, "mouth_corner_l", "mouth_corner_r")
    assert wider >= human.d(0.2)
    d = human.moved({"AU20": 1.0})
    for side in "lr":
        assert abs(d[f"mouth_corner_{side}"][Y]) <= human.d(0.03)


@pytest.mark.parametrize("au", ["AU23", "AU24"])
def test_au23_au24_narrow_and_press_the_lips(human: Face, au: str) -> None:
    """FACS AU23 Lip Tightener and AU24 Lip Pressor (orbicularis oris): the lips narrow and thin (23) or
    press together (24) (facs-human.md §1)."""
    rest, p = human.rest, human.at({au: 1.0})
    narrower = _gap(rest, "mouth_corner_l", "mouth_corner_r") - _gap(p, "mouth_corner_l", "mouth_corner_r")
    # issue 11: 0.015 D (1.0 mm) before the sphincter's ring falloff; now 4.2 mm (AU23) / 3.4 mm (AU24)
    assert narrower >= human.d(0.045)
    closer = _gap(rest, "anchor_upper_lip", "anchor_lower_lip", Y) - _gap(p, "anchor_upper_lip", "anchor_lower_lip", Y)
    assert closer >= human.d(0.025)


def test_au23_thins_the_red_of_the_lips(human: Face) -> None:
    """FACS AU23 Lip Tightener: the red parts of the lips narrow (thinner lips) and the mouth narrows
    (facs-human.md §1). Measured by the upper- and lower-lip points 12 mm either side of the midline."""
    rest, p = human.rest, human.at({"AU23": 1.0})
    for side in "lr":
        thinner = _gap(rest, f"upper_lip_{side}", f"lower_lip_{side}", Y) - _gap(
            p, f"upper_lip_{side}", f"lower_lip_{side}", Y
        )
        assert thinner >= human.d(0.015)  # 1.0 mm; measured 1.35 mm


def test_au26_au27_drop_the_jaw_in_an_oval(human: Face) -> None:
    """FACS AU26 Jaw Drop / AU27 Mouth Stretch: the mandible is lowered, the lips part; the corners
    follow part way so the opening is an oval, not two flaps; 27 opens wider than 26 (facs-human.md §1)."""
    openings = []
    for au in ("AU26", "AU27"):
        d = human.moved({au: 1.0})
        opening = d["anchor_upper_lip"][Y] - d["anchor_lower_lip"][Y]
        assert opening >= human.d(0.25)
        assert d["chin"][Y] <= -human.d(0.2)
        for side in "lr":  # corners move half way: between not moving and moving with the lower lip
            assert 0.2 * d["anchor_lower_lip"][Y] >= d[f"mouth_corner_{side}"][Y] >= 0.8 * d["anchor_lower_lip"][Y]
        openings.append(opening)
    assert openings[1] >= 1.4 * openings[0]


def test_au43_closes_the_eyes(human: Face) -> None:
    """FACS AU43 Eyes Closed (levator relaxed + orbicularis oculi): the upper lid comes down to the lower
    lid (facs-human.md §1)."""
    p = human.at({"AU43": 1.0})
    for side in "lr":
        assert p[f"margin_upper_lid_{side}"][Y] <= p[f"margin_lower_lid_{side}"][Y] + 0.5


def test_au46_winks_one_eye_only(human: Face) -> None:
    """FACS AU46 Wink (AU45 on one side): one eye closes, the other stays open -- separate lid servos
    (facs-human.md §1)."""
    p, rest = human.at({"AU46L": 1.0}), human.rest
    assert p["margin_upper_lid_l"][Y] <= p["margin_lower_lid_l"][Y] + 0.5
    assert abs(p["margin_upper_lid_r"][Y] - rest["margin_upper_lid_r"][Y]) <= 0.1
    assert abs(p["margin_lower_lid_r"][Y] - rest["margin_lower_lid_r"][Y]) <= 0.1


@pytest.mark.parametrize("au, sign", [("AU65", 1.0), ("AU66", -1.0)])
def test_au65_au66_turn_the_eyes_apart_or_together(human: Face, au: str, sign: float) -> None:
    """FACS AU65 Walleye / AU66 Cross-eye: each eye turns outwards / inwards -- independent eye pan
    (facs-human.md §1: 'independent per-eye pan (vergence)')."""
    d = human.moved({au: 1.0})
    assert sign * d["centre_pupil_l"][X] >= human.d(0.04)
    assert -sign * d["centre_pupil_r"][X] >= human.d(0.04)


def test_au61_turns_both_eyes_the_same_way(human: Face) -> None:
    """FACS AU61 Eyes Turn Left: both eyes to the head's left (facs-human.md §1)."""
    d = human.moved({"AU61": 1.0})
    assert d["centre_pupil_l"][X] >= human.d(0.06) and d["centre_pupil_r"][X] >= human.d(0.06)


# --- human: the six basic emotions (EMFACS prototypes, facs-human.md §2a) ------------------------------


def test_anger_lowers_and_knits_the_brows_and_presses_the_lips(human: Face) -> None:
    """EMFACS anger 4 + 5 + 7 + 23 (facs-human.md §2a): brows down and together, a hard stare with the
    lower lid raised, the lips pressed thin."""
    rest, p = human.rest, human.at(human.expression("anger"))
    d = {k: p[k] - rest[k] for k in p}
    assert d["anchor_brow_inner_l"][Y] <= -human.d(0.03) and d["anchor_brow_inner_r"][Y] <= -human.d(0.03)
    assert _gap(rest, "anchor_brow_knit_l", "anchor_brow_knit_r") - _gap(
        p, "anchor_brow_knit_l", "anchor_brow_knit_r"
    ) >= human.d(0.08)
    assert d["margin_lower_lid_l"][Y] >= human.d(0.03)
    assert _gap(rest, "anchor_upper_lip", "anchor_lower_lip", Y) - _gap(
        p, "anchor_upper_lip", "anchor_lower_lip", Y
    ) >= human.d(0.02)


def test_disgust_wrinkles_the_nose_and_raises_the_upper_lip(human: Face) -> None:
    """EMFACS disgust 9 + 15 + 16 (+ 10; facs-human.md §2a): nose wrinkled, upper lip raised, corners
    and lower lip down -- not a pout."""
    d = human.moved(human.expression("disgust"))
    assert d["nose_wing_l"][Y] >= human.d(0.02) and d["upper_lip_l"][Y] >= human.d(0.05)
    assert d["anchor_lower_lip"][Y] <= -human.d(0.03)
    assert d["mouth_corner_l"][Y] <= 0.0


def test_fear_raises_and_draws_the_brows_opens_the_eyes_and_stretches_the_mouth(human: Face) -> None:
    """EMFACS fear 1 + 2 + 4 + 5 + 20 + 26 (facs-human.md §2a)."""
    rest, p = human.rest, human.at(human.expression("fear"))
    d = {k: p[k] - rest[k] for k in p}
    assert d["anchor_brow_inner_l"][Y] >= human.d(0.04) and d["margin_upper_lid_l"][Y] >= human.d(0.04)
    assert _gap(p, "mouth_corner_l", "mouth_corner_r") - _gap(rest, "mouth_corner_l", "mouth_corner_r") >= human.d(0.15)
    assert d["anchor_upper_lip"][Y] - d["anchor_lower_lip"][Y] >= human.d(0.08)


def test_surprise_raises_the_brows_and_lids_and_drops_the_jaw(human: Face) -> None:
    """EMFACS surprise 1 + 2 + 5B + 26 (facs-human.md §2a)."""
    d = human.moved(human.expression("surprise"))
    assert d["anchor_brow_inner_l"][Y] >= human.d(0.08) and d["anchor_brow_outer_l"][Y] >= human.d(0.08)
    assert d["margin_upper_lid_l"][Y] >= human.d(0.03)
    assert d["anchor_upper_lip"][Y] - d["anchor_lower_lip"][Y] >= human.d(0.25)


def test_sadness_raises_the_inner_brows_and_drops_the_corners(human: Face) -> None:
    """EMFACS sadness 1 + 4 + 15 (facs-human.md §2a): inner brows up and together, corners down."""
    rest, p = human.rest, human.at(human.expression("sadness"))
    d = {k: p[k] - rest[k] for k in p}
    # the head is pitched down 7.5 deg in sadness (AU54): brows against the eye centres, corners
    # against the mouth centre
    assert d["anchor_brow_inner_l"][Y] - d["eye_centre_l"][Y] >= human.d(0.04)
    assert _gap(rest, "anchor_brow_inner_l", "anchor_brow_inner_r") - _gap(
        p, "anchor_brow_inner_l", "anchor_brow_inner_r"
    ) >= human.d(0.03)
    for side in "lr":
        assert (d[f"mouth_corner_{side}"][Y] - d["mouth_centre"][Y]) <= -human.d(0.06)


def test_happiness_raises_the_corners_and_cheeks(human: Face) -> None:
    """EMFACS happiness 6 + 12 (facs-human.md §2a)."""
    d = human.moved(human.expression("happiness"))
    assert d["mouth_corner_l"][Y] >= human.d(0.08) and d["mouth_corner_r"][Y] >= human.d(0.08)
    assert d["margin_lower_lid_l"][Y] >= human.d(0.02)


# --- dog: DFACS (dfacs-dog.md §2, after Navarro Newball 2010 Table 5.3) ---------------------------------


def test_dog_au1_raises_the_flews_and_its_counter_relaxes_them(dog: Face) -> None:
    """DFACS AU1 lip raise / snarl (levator nasolabialis): the upper lip (flew) above the canine goes up
    and back; counter: relaxed, down (dfacs-dog.md §2)."""
    assert dog.moved({"AU1": 1.0})["anchor_lip_raise_l"][Y] >= dog.d(0.08)
    assert dog.moved({"AU1": -1.0})["anchor_lip_raise_l"][Y] <= -dog.d(0.02)


def test_dog_au1_lifts_the_flew_off_the_lower_lip(dog: Face) -> None:
    """DFACS AU1 lip raise / snarl: the upper lip retracts and the teeth are bared (dfacs-dog.md §2;
    Londra anger 'lips retracted, teeth bared'). The lips part at the flew: before the slit gate
    (sim/muscles/slit.py) the lower lip rose with it and the gap was 0."""
    near = (36.0, 8.0, 160.0)
    assert abs(dog.lip_gap_mm({}, near)) <= 1e-6
    assert dog.lip_gap_mm({"AU1": 1.0}, near) >= dog.d(0.05)  # 2.7 mm; measured 4.0 mm


def test_dog_au2_pulls_the_mouth_corners_back(dog: Face) -> None:
    """DFACS AU2 contract mouth corner (zygomaticus): the commissure is pulled back (dfacs-dog.md §2)."""
    for side in "lr":
        assert dog.moved({"AU2": 1.0})[f"anchor_mouth_corner_{side}"][Z] <= -dog.d(0.15)


def test_dog_au3_dilates_the_nostrils(dog: Face) -> None:
    """DFACS AU3 dilate nostril (nostril dilators + levator nasi): the nostril wings go out
    (dfacs-dog.md §2)."""
    d = dog.moved({"AU3": 1.0})
    assert d["anchor_nostril_wing_l"][X] >= dog.d(0.04) and d["anchor_nostril_wing_r"][X] <= -dog.d(0.04)


def test_dog_au4_lowers_the_lids_and_brow_and_its_counter_raises_the_brow(dog: Face) -> None:
    """DFACS AU4 depress eyelids (levator anguli oculi, frontalis, orbicularis oculi); counter: relax
    eyelids, the medial brow up -- the 'puppy-dog' brow (dfacs-dog.md §2)."""
    d = dog.moved({"AU4": 1.0})
    assert d["margin_upper_lid_l"][Y] <= -dog.d(0.07) and d["anchor_brow_l"][Y] <= -dog.d(0.04)
    assert dog.moved({"AU4": -1.0})["anchor_brow_l"][Y] >= dog.d(0.03)


def test_dog_au5_turns_the_ears_forward_and_its_counter_lays_them_back_flat(dog: Face) -> None:
    """DFACS AU5 forward ears (auriculares rostrales); counter: backward ears, laid back along the skull
    (dfacs-dog.md §2; fear, §3)."""
    fwd, back = dog.moved({"AU5": 1.0}), dog.moved({"AU5": -1.0})
    for side in "lr":
        assert fwd[f"tip_ear_{side}"][Z] >= dog.d(0.3)
        assert fwd[f"anchor_ear_root_{side}"][Z] >= dog.d(0.05)
        assert back[f"tip_ear_{side}"][Z] <= -dog.d(0.5) and back[f"tip_ear_{side}"][Y] <= -dog.d(0.3)


def test_dog_au6_counter_lowers_the_ears(dog: Face) -> None:
    """DFACS AU6 raise ears; counter: lower ears, the tips go out and down (dfacs-dog.md §2)."""
    d = dog.moved({"AU6": -1.0})
    assert d["tip_ear_l"][Y] <= -dog.d(0.25) and d["tip_ear_l"][X] >= dog.d(0.3)
    assert dog.moved({"AU6": 1.0})["anchor_forehead_l"][Z] <= -dog.d(0.05)  # forehead skin drawn back


def test_dog_au7_opens_the_mandible(dog: Face) -> None:
    """DFACS AU7 open mandible (jaw pitch about the TMJ): the chin drops, the mouth opens
    (dfacs-dog.md §2)."""
    d = dog.moved({"AU7": 1.0})
    assert d["mandible_front"][Y] <= -dog.d(0.6)
    assert abs(d["mouth_front"][Y]) <= dog.d(0.02)  # the upper jaw stays


def test_dog_au8_moves_the_mandible_sideways(dog: Face) -> None:
    """DFACS AU8 left mandible (lateral jaw rotation) (dfacs-dog.md §2)."""
    assert dog.moved({"AU8": 1.0})["mandible_front"][X] >= dog.d(0.2)


@pytest.mark.parametrize("au, axis, sign", [("AU12", X, 1.0), ("AU13", Y, 1.0), ("AU13", Y, -1.0)])
def test_dog_eye_aus_turn_the_eyes(dog: Face, au: str, axis: int, sign: float) -> None:
    """DFACS AU12 left eyes / AU13 raise eyes (and lower eyes, its counter) (dfacs-dog.md §2)."""
    d = dog.moved({au: sign})
    for side in "lr":
        assert sign * d[f"centre_pupil_{side}"][axis] >= dog.d(0.04)


def test_dog_au14_and_au15_close_the_lids(dog: Face) -> None:
    """DFACS AU14 retract eyes (robot: lids narrow) and AU15 blink eyelid (dfacs-dog.md §2)."""
    assert dog.moved({"AU14": 1.0})["margin_upper_lid_l"][Y] <= -dog.d(0.04)
    assert dog.moved({"AU15": 1.0})["margin_upper_lid_l"][Y] <= -dog.d(0.12)


def test_dog_au18_shows_the_tongue_tip(dog: Face) -> None:
    """DFACS AU18 show tongue tip (tongue kinematics, tip pushed out and rotated) (dfacs-dog.md §2)."""
    assert float(np.linalg.norm(dog.moved({"AU18": 1.0})["tip_tongue_tip"])) >= dog.d(0.1)


def test_dog_fear_lays_the_ears_back_and_flat(dog: Face) -> None:
    """Londra fear: -14, -5, -9 (relax eyes, ears back, head down; dfacs-dog.md §3), ears back and flat."""
    rest, p = dog.rest, dog.at(dog.expression("fear"))
    for side in "lr":
        # in the head's own frame: remove the head-down pitch by comparing the tip with the ear root
        rel_rest = rest[f"tip_ear_{side}"] - rest[f"anchor_ear_root_{side}"]
        rel = p[f"tip_ear_{side}"] - p[f"anchor_ear_root_{side}"]
        assert rel[Y] <= rel_rest[Y] - dog.d(0.4)


def test_dog_anger_retracts_the_lips_and_bares_the_teeth(dog: Face) -> None:
    """Londra anger: 14, 4, 1, 2, 5, 7 (dfacs-dog.md §3): flews up, corners back, mouth open."""
    d = dog.moved(dog.expression("anger_without_tongue"))
    assert d["anchor_lip_raise_l"][Y] >= dog.d(0.08) and d["anchor_mouth_corner_l"][Z] <= -dog.d(0.12)
    assert d["mandible_front"][Y] <= -dog.d(0.2)


def test_dog_happiness_has_a_relaxed_open_mouth(dog: Face) -> None:
    """Londra happiness 6, 9 with a relaxed open mouth (dfacs-dog.md §5: recognised only as attention
    without it): the jaw drops, the flews relax, the tongue shows."""
    rest, p = dog.rest, dog.at(dog.expression("happiness"))
    chin_drop = (rest["mouth_front"][Y] - rest["mandible_front"][Y]) - (p["mouth_front"][Y] - p["mandible_front"][Y])
    assert chin_drop <= -dog.d(0.2)
