"""Plausibility of a head's size: a mesh exported in metres (or inches) loads silently at the wrong scale.

`size_warnings` returns one message per suspicious item, with the size found and the likely fix; the
profile stays valid (a tiny test rig is allowed), so ``servoface check`` prints these as warnings.
"""

from __future__ import annotations

from typing import Any

import numpy as np

HEAD_SPAN_MM = (40.0, 1500.0)  # a face a servo can move: a few cm to a large animatronic
PART_MIN_MM = 1.0
# a hard bound on every position and length in a head profile and its meshes (after ``scale``): far beyond
# any head, so only a wrong unit or a typo reaches it, and below it squares and products stay finite
COORD_LIMIT_MM = 10_000.0


def _span(vertices: Any) -> float:
    v = np.asarray(vertices, dtype=np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) if len(v) else 0.0


def _hint(span_mm: float) -> str:
    if span_mm < HEAD_SPAN_MM[0]:
        factor = 1000.0 if span_mm * 1000.0 <= HEAD_SPAN_MM[1] else 25.4
        return f"a mesh in metres? set scale = {factor:g} on it (25.4 for inches)"
    return "a mesh in 1/10 mm or the wrong unit? set scale (e.g. 0.1, 0.001)"


def size_warnings(head: Any) -> list[str]:
    """Messages for a head (skin + parts at rest) or a part whose size is implausible for a servo head."""
    out = []
    chunks = [np.asarray(p.mesh.vertices) for p in head.parts]
    if head.skin.vertices_mm.shape[0]:
        chunks.append(np.asarray(head.skin.vertices_mm))
        span = _span(head.skin.vertices_mm)
        if not HEAD_SPAN_MM[0] <= span <= HEAD_SPAN_MM[1]:
            out.append(
                f"skin.mesh is {span:.3g} mm across (expected {HEAD_SPAN_MM[0]:g}..{HEAD_SPAN_MM[1]:g}): {_hint(span)}"
            )
    for i, p in enumerate(head.parts):
        span = _span(p.mesh.vertices)
        if span < PART_MIN_MM:
            out.append(f"part[{i}] {p.name!r} is {span:.3g} mm across: {_hint(span)}")
    if chunks:
        span = _span(np.concatenate(chunks))
        if not HEAD_SPAN_MM[0] <= span <= HEAD_SPAN_MM[1]:
            out.append(
                f"the head is {span:.3g} mm across (expected {HEAD_SPAN_MM[0]:g}..{HEAD_SPAN_MM[1]:g} mm): "
                f"{_hint(span)}"
            )
    else:
        out.append("the head has no skin and no parts: nothing to draw or check for collisions")
    return out
