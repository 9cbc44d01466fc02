"""Colours and surface finish of the head's parts, chosen so an expression reads in a small image.

pyrender shades in linear light and gamma-encodes its output, so the sRGB colours a head declares are
converted to linear here. Finish is chosen from the part's name: glossy eyes (a specular glint makes gaze
readable), semi-matte skin, a dark, matte mouth cavity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

RGBA = tuple[float, float, float, float]

MOUTH_CAVITY_RGBA: RGBA = (0.22, 0.05, 0.06, 1.0)  # the inside of the skin, seen through the open mouth
SCLERA_RGB = (0.95, 0.94, 0.92)
IRIS_RGB = {"human": (0.30, 0.20, 0.12), "dog": (0.42, 0.25, 0.08)}
PUPIL_RGB = (0.03, 0.03, 0.03)


@dataclass(frozen=True)
class Finish:
    """PBR parameters of a surface (metallic-roughness model, metallic 0 for everything organic)."""

    roughness: float
    metallic: float = 0.0


FINISHES: dict[str, Finish] = {
    "eyeball": Finish(0.15),
    "lid": Finish(0.6),
    "teeth": Finish(0.35),
    "tooth": Finish(0.35),
    "tongue": Finish(0.4),
    "nose": Finish(0.35),
    "skin": Finish(0.62),
    "cavity": Finish(0.9),
}
DEFAULT_FINISH = Finish(0.6)


def finish_for(part_name: str) -> Finish:
    """The finish of a part by name (first keyword found in the name wins, e.g. ``eyeball_l``)."""
    for key, finish in FINISHES.items():
        if key in part_name:
            return finish
    return DEFAULT_FINISH


def srgb_to_linear(rgba: RGBA | tuple[float, ...]) -> NDArray[np.float64]:
    """sRGB colour (0..1) to linear light; alpha unchanged. Raises ValueError outside 0..1."""
    c = np.asarray(rgba, dtype=np.float64)
    if c.shape not in ((3,), (4,)) or not np.all(np.isfinite(c)) or c.min() < 0 or c.max() > 1:
        raise ValueError(f"colour must be 3 or 4 numbers in 0..1, got {rgba!r}")
    out = c.copy()
    rgb = c[:3]
    out[:3] = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    if out.shape == (3,):
        out = np.append(out, 1.0)
    return out


def srgb_to_linear_array(rgba: NDArray[np.floating]) -> NDArray[np.float32]:
    """(n, 3|4) sRGB colours in 0..1 to (n, 4) linear float32 (alpha 1 if not given)."""
    c = np.asarray(rgba, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] not in (3, 4):
        raise ValueError(f"colours must be (n, 3) or (n, 4), got {c.shape}")
    out = np.ones((len(c), 4), dtype=np.float64)
    out[:, : c.shape[1]] = c
    rgb = np.clip(out[:, :3], 0.0, 1.0)
    out[:, :3] = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return out.astype(np.float32)


def eye_vertex_colors(
    vertices_mm: NDArray[np.floating],
    face_type: str = "human",
    iris_half_angle_deg: float = 28.0,
    pupil_half_angle_deg: float = 13.0,
) -> NDArray[np.float32]:
    """Linear RGBA per vertex painting sclera, iris and pupil on an eyeball looking along +z at rest.

    vertices_mm: (n, 3) of the eyeball at rest (head frame); its centre is the mean of the bounding box.
    A dog's eye is mostly iris (little visible sclera), so the iris is larger for ``face_type`` "dog".
    """
    v = np.asarray(vertices_mm, dtype=np.float64)
    centre = (v.min(axis=0) + v.max(axis=0)) / 2.0
    d = v - centre
    cos_angle = d[:, 2] / np.maximum(np.linalg.norm(d, axis=1), 1e-9)
    angle = np.degrees(np.arccos(np.clip(cos_angle, -1.0, 1.0)))
    if face_type == "dog":
        iris_half_angle_deg, pupil_half_angle_deg = 50.0, 22.0
    iris = srgb_to_linear(IRIS_RGB.get(face_type, IRIS_RGB["human"]))
    # soft edges (a few degrees) so a coarse sphere still shows round, not jagged, circles
    t_pupil = np.clip((angle - pupil_half_angle_deg) / 3.0 + 0.5, 0.0, 1.0)[:, None]
    t_iris = np.clip((angle - iris_half_angle_deg) / 4.0 + 0.5, 0.0, 1.0)[:, None]
    colour = (1 - t_pupil) * srgb_to_linear(PUPIL_RGB) + t_pupil * iris
    colour = (1 - t_iris) * colour + t_iris * srgb_to_linear(SCLERA_RGB)
    out: NDArray[np.float32] = colour.astype(np.float32)
    return out
