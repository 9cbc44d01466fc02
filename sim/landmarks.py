"""Face landmarks of a posed head, and the twin's fidelity: the muscle model's target face against the
face the servos make (the *achievable* face).

The landmark set of a head (``landmark_set``), all in the head frame, mm:

- **profile points**: every ``[landmarks]`` entry of ``head.toml`` (the built-ins list eye centres, mouth
  corners and centre, nose tip, chin, jaw pivot, brow, lip and cheek points; the dog also ear bases and the
  muzzle). A point within ``SKIN_SNAP_MM`` of the skin is the nearest skin vertex; a point inside the
  head (an eye centre, the jaw pivot) rides with the rigid part whose mesh is nearest to it;
- **anchor points**: the skin vertex of every anchor actuator (brows, lips, mouth corners, nose, cheeks,
  chin; dog: flews, brow, forehead, ear roots, nostrils, muzzle);
- **lid margins**: the front-most vertex of every ``*_lid_*`` part (it sits on the margin's centre);
- **pupils**: the centroid of every ``pupil_*`` part;
- **tips** (dog): the vertex of every ``ear_*`` part and of ``tongue_tip`` farthest from the joint
  that carries it.

``achievable_pose`` is what the twin shows for a frame: the muscle model's actuator targets, through the
calibration to integer goal ticks and back (what the servos are told), posed by
``FaceModel.pose_from_targets``. ``fidelity`` compares the two faces at every landmark;
``library_fidelity`` runs every library expression and every single AU at +1 (and at -1 where the AU
has a counter) -- the figure ``servoface bench face`` prints.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.errors import HeadProfileError
from servoface.sim.kinematics import part_transforms, posed_skin_vertices
from servoface.sim.rig import HeadPose

FloatArray = NDArray[np.float64]
SKIN_SNAP_MM = 3.0  # a profile point this close to the skin is a skin landmark


@dataclass(frozen=True)
class Landmark:
    """One landmark: on the skin (``vertex`` of the skin) or on a rigid part (``point_mm`` in its rest
    frame, moved by the part's transform)."""

    name: str
    part: str | None  # None = skin
    vertex: int = -1
    point_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)


class LandmarkSet:
    """The landmarks of one head; ``positions(pose)`` gives them (L, 3) for a pose."""

    def __init__(self, head: Any, landmarks: list[Landmark]) -> None:
        self.head = head
        self.landmarks = tuple(landmarks)
        self.names = tuple(lm.name for lm in landmarks)
        self.index = {n: i for i, n in enumerate(self.names)}
        self._skin_rows = np.array([i for i, lm in enumerate(landmarks) if lm.part is None], dtype=np.int64)
        self._skin_vertices = np.array([lm.vertex for lm in landmarks if lm.part is None], dtype=np.int64)
        self._rigid = [(i, lm.part, np.array(lm.point_mm)) for i, lm in enumerate(landmarks) if lm.part is not None]

    def __len__(self) -> int:
        return len(self.landmarks)

    def positions(self, pose: HeadPose) -> FloatArray:
        """(L, 3) float: every landmark for ``pose`` (skin skinned and deformed, parts moved)."""
        out = np.zeros((len(self.landmarks), 3))
        if self._skin_rows.size:
            out[self._skin_rows] = posed_skin_vertices(self.head, pose)[self._skin_vertices]
        if self._rigid:
            tfs = part_transforms(self.head, pose.joint_deg)
            for row, part, p in self._rigid:
                tf = tfs[str(part)]
                out[row] = tf[:3, :3] @ p + tf[:3, 3]
        return out

    def position(self, pose: HeadPose, name: str) -> FloatArray:
        """(3,) float: one landmark by name (KeyError naming the known ones if unknown)."""
        if name not in self.index:
            raise KeyError(f"landmark {name!r}: not in this head's set ({', '.join(self.names)})")
        out: FloatArray = self.positions(pose)[self.index[name]]
        return out


def landmark_set(head: Any) -> LandmarkSet:
    """The documented landmark set of ``head`` (see the module docstring)."""
    rest = np.asarray(head.skin.vertices_mm, dtype=np.float64)
    parts = {p.name: p for p in head.parts}
    joints = {j.name: j for j in head.joints}
    out: list[Landmark] = []
    for name, point in head.landmarks_mm.items():
        p = np.asarray(point, dtype=np.float64)
        d = np.linalg.norm(rest - p, axis=1)
        v = int(np.argmin(d))
        if d[v] <= SKIN_SNAP_MM:
            out.append(Landmark(name, None, vertex=v))
            continue
        best, best_d = None, np.inf
        for part in head.parts:
            pd = float(np.min(np.linalg.norm(np.asarray(part.mesh.vertices) - p, axis=1)))
            if pd < best_d:
                best, best_d = part.name, pd
        out.append(Landmark(name, best, point_mm=(float(p[0]), float(p[1]), float(p[2]))))
    for act in head.actuators:
        vertex = getattr(act, "vertex", None)
        if vertex is not None:
            out.append(Landmark(f"anchor_{act.role}", None, vertex=int(vertex)))
    for name, part in parts.items():
        verts = np.asarray(part.mesh.vertices, dtype=np.float64)
        if name.startswith(("upper_lid", "lower_lid")):
            front = verts[int(np.argmax(verts[:, 2]))]
            out.append(Landmark(f"margin_{name}", name, point_mm=_tuple(front)))
        elif name.startswith("pupil"):
            out.append(Landmark(f"centre_{name}", name, point_mm=_tuple(verts.mean(axis=0))))
        elif (name.startswith("ear_") or name == "tongue_tip") and part.joint in joints:
            joint = joints[part.joint]
            if joint.name.startswith(("ear", "tongue")):
                tip = verts[int(np.argmax(np.linalg.norm(verts - np.asarray(joint.pivot_mm), axis=1)))]
                out.append(Landmark(f"tip_{name}", name, point_mm=_tuple(tip)))
    return LandmarkSet(head, out)


def _tuple(v: FloatArray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def achievable_pose(model: Any, calibration: Any, target: HeadPose) -> HeadPose:
    """The face the servos make for a target pose: its actuator targets -> goal ticks (the calibration)
    -> the targets those ticks mean -> ``model.pose_from_targets`` (the twin)."""
    goals = calibration.targets_to_goals(target.actuator_targets)
    back = calibration.goals_to_targets(goals, clip=True)
    pose: HeadPose = model.pose_from_targets({role: back[role] for role in target.actuator_targets if role in back})
    return pose


@dataclass(frozen=True)
class FidelityCase:
    """One frame's fidelity: the largest landmark error (mm) and where it is."""

    case: str
    max_error_mm: float
    landmark: str


def fidelity(
    landmarks: LandmarkSet, model: Any, calibration: Any, aus: Mapping[str, float], case: str = ""
) -> FidelityCase:
    """Max landmark distance (mm) between the muscle model's face for ``aus`` and the achievable face."""
    target = model.solve(aus)
    got = achievable_pose(model, calibration, target)
    err = np.linalg.norm(landmarks.positions(target) - landmarks.positions(got), axis=1)
    i = int(np.argmax(err))
    return FidelityCase(case, float(err[i]), landmarks.names[i])


def fidelity_cases(model: Any, library: Mapping[str, Any]) -> Iterator[tuple[str, dict[str, float]]]:
    """Every library expression's apex, then every AU of the table alone at +1 (and -1 if signed)."""
    for name, expression in library.items():
        yield name, dict(expression.apex())
    table = model.mapping.table
    for number in sorted(table.entries):
        au = f"AU{number}"
        yield au, {au: 1.0}
        if table.entries[number].range[0] < 0.0:
            yield f"{au}-", {au: -1.0}


def library_fidelity(head_name: str) -> list[FidelityCase]:
    """``fidelity`` of every case of ``fidelity_cases`` on a built-in head (or a profile folder)."""
    from servoface.calibration import load_calibration
    from servoface.sim.expressions import load_library
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head

    head = load_head(head_name)
    if head.calibration_path is None:
        raise HeadProfileError(f"head {head.name!r} names no calibration file: fidelity needs one")
    model = FaceModel(head)
    calibration = load_calibration(head.calibration_path)
    landmarks = landmark_set(head)
    library = load_library(head.expressions_path or head.face_type)
    return [fidelity(landmarks, model, calibration, aus, case) for case, aus in fidelity_cases(model, library)]
