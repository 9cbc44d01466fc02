"""Left/right convention and mirror mode.

AU side suffixes (``AU12L``) are the subject's OWN side, and a robot face's own left is the same
convention (facs-human.md, "Sides"); ARKit's and MediaPipe's ``...Left`` blendshapes are the subject's own
side too. So by default a tracked person's left mouth corner drives the robot's left mouth corner
(puppeteering). A robot that imitates a person FACING it behaves like a mirror image: ``mirror=True``
swaps every L/R pair and every lateral head/eye action (human AU51<->52, AU55<->56, AU61<->62; DFACS
signed lateral AUs 8, 10, 11, 12 change sign). Up/down and symmetric actions are unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping

from servoface.sim.rig import FaceType

_HUMAN_SWAP: dict[str, str] = {
    "AU51": "AU52",
    "AU52": "AU51",
    "AU55": "AU56",
    "AU56": "AU55",
    "AU61": "AU62",
    "AU62": "AU61",
}
_DOG_NEGATE: frozenset[str] = frozenset({"AU8", "AU10", "AU11", "AU12"})


def mirror_name(name: str, face_type: FaceType) -> str:
    """The mirrored AU name of a canonical name (``AU12L`` -> ``AU12R``, human ``AU51`` -> ``AU52``)."""
    if name.endswith("L"):
        return name[:-1] + "R"
    if name.endswith("R"):
        return name[:-1] + "L"
    if face_type == "human":
        return _HUMAN_SWAP.get(name, name)
    return name


def mirror_aus(aus: Mapping[str, float], face_type: FaceType) -> dict[str, float]:
    """``aus`` as a mirror image: L/R swapped, lateral head/eye actions swapped (human) or negated (dog)."""
    out: dict[str, float] = {}
    for name, value in aus.items():
        mirrored = mirror_name(name, face_type)
        base = mirrored.rstrip("LR")
        out[mirrored] = -value if face_type == "dog" and base in _DOG_NEGATE else value
    return out
