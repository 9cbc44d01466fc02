"""MediaPipe FaceLandmarker results written as JSON -> servoface messages.

What people dump from MediaPipe (Python ``FaceLandmarkerResult`` turned into dicts, or the JS result as
JSON): ``face_blendshapes`` — a list with one list per face of ``{"index", "score", "category_name",
"display_name"}`` (JS: ``faceBlendshapes: [{"categories": [{"categoryName", "score"}]}]``; a single flat list
is one face); ``facial_transformation_matrixes`` (JS ``facialTransformationMatrixes``, 4x4 nested lists or
``{"rows", "columns", "data"}``); a time ``timestamp_ms`` (or ``t``). :func:`normalise_result` turns one
such object into ``{"t", "blendshapes", "head"}`` for face ``face_id`` (default 0), and raises
:class:`NoFace` when that face is not in the result (the tracker saw nobody: a lost row).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from servoface.controller.inputs.errors import InputError

SHAPES_KEYS = ("face_blendshapes", "faceBlendshapes")
MATRIX_KEYS = ("facial_transformation_matrixes", "facialTransformationMatrixes")
TIME_KEYS = ("timestamp_ms", "timestampMs")
IGNORED_KEYS = frozenset({"face_landmarks", "faceLandmarks"})


class NoFace(InputError):
    """The result has no (such) face."""


def is_result(obj: Any) -> bool:
    return isinstance(obj, Mapping) and any(k in obj for k in SHAPES_KEYS + MATRIX_KEYS)


def normalise_result(obj: Mapping[str, Any], *, face_id: int = 0, where: str = "message") -> dict[str, Any]:
    """One MediaPipe result object -> a servoface message dict (see the module doc)."""
    out: dict[str, Any] = {}
    for key, value in obj.items():
        if key in SHAPES_KEYS:
            faces = _faces(value, f"{where}.{key}")
            if face_id >= len(faces):
                raise NoFace(f"{where}.{key}: no face {face_id} ({len(faces)} faces in this result)")
            out["blendshapes"] = _categories(faces[face_id], f"{where}.{key}[{face_id}]")
        elif key in MATRIX_KEYS:
            if not isinstance(value, list):
                raise InputError(f"{where}.{key}: expected a list of 4x4 matrices, got {type(value).__name__}")
            if face_id < len(value):
                out["head"] = {"matrix": _matrix(value[face_id], f"{where}.{key}[{face_id}]")}
        elif key in TIME_KEYS:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(f"{where}.{key}: expected a time in milliseconds, got {value!r}")
            out["t"] = float(value) / 1e3
        elif key in IGNORED_KEYS:
            continue
        else:
            out[key] = value
    if "blendshapes" not in out and "head" not in out and "aus" not in out:
        raise NoFace(f"{where}: no face in this MediaPipe result")
    return out


def _faces(value: Any, where: str) -> list[Any]:
    if not isinstance(value, list):
        raise InputError(f"{where}: expected a list (one entry per face), got {type(value).__name__}")
    if value and isinstance(value[0], Mapping) and ("score" in value[0]):
        return [value]  # a flat list of categories: one face
    return [v["categories"] if isinstance(v, Mapping) and "categories" in v else v for v in value]


def _categories(face: Any, where: str) -> dict[str, Any]:
    if not isinstance(face, list):
        raise InputError(f"{where}: expected a list of {{category_name, score}}, got {type(face).__name__}")
    scores: dict[str, Any] = {}
    for i, cat in enumerate(face):
        if not isinstance(cat, Mapping):
            raise InputError(f"{where}[{i}]: expected {{category_name, score}}, got {type(cat).__name__}")
        name = cat.get("category_name", cat.get("categoryName"))
        if not isinstance(name, str) or "score" not in cat:
            raise InputError(f"{where}[{i}]: expected category_name (text) and score")
        scores[name] = cat["score"]
    return scores


def _matrix(value: Any, where: str) -> Any:
    if isinstance(value, Mapping) and "data" in value:
        return value["data"]
    return value
