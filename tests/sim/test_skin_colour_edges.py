"""The skins' colour edges (session 36): the dog's nose pad and lips and the human's lips are coloured per
vertex, with edges sharper than the skin's grid is fine there, so they were drawn along the grid's triangles
as a saw-tooth (the dog: spikes under the nose pad, blotches on the upper lip; the human: slanted, notched
lip ends, different left and right). Measured on the mesh: the curves where the vertex colours' lightness,
interpolated over the triangles as the renderer does, crosses a level."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.heads import dog_gen, human_gen

LUMA = np.array([0.299, 0.587, 0.114])


def _iso_lines(verts: np.ndarray, faces: np.ndarray, value: np.ndarray, level: float) -> list[np.ndarray]:
    """The polylines (k, 3) along which ``value`` (per vertex, linear over each triangle) crosses ``level``."""
    side = value[faces] >= level
    crossed: dict[tuple[int, int], np.ndarray] = {}
    links: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for f, s in zip(faces, side, strict=True):
        cut = []
        for a, b in ((0, 1), (1, 2), (2, 0)):
            if s[a] != s[b]:
                key = (min(int(f[a]), int(f[b])), max(int(f[a]), int(f[b])))
                t = (level - value[key[0]]) / (value[key[1]] - value[key[0]])
                crossed[key] = verts[key[0]] + t * (verts[key[1]] - verts[key[0]])
                cut.append(key)
        if len(cut) == 2:
            links.setdefault(cut[0], []).append(cut[1])
            links.setdefault(cut[1], []).append(cut[0])
    seen: set[tuple[int, int]] = set()
    lines = []
    for start in links:
        if start in seen:
            continue
        seen.add(start)
        line = [start]
        for grow_front in (False, True):
            while True:
                end = line[0] if grow_front else line[-1]
                nxt = [k for k in links[end] if k not in seen]
                if not nxt:
                    break
                seen.add(nxt[0])
                if grow_front:
                    line.insert(0, nxt[0])
                else:
                    line.append(nxt[0])
        lines.append(np.array([crossed[k] for k in line]))
    return lines


def _turns_deg(line: np.ndarray, step_mm: float) -> np.ndarray:
    """Turning angles of a polyline resampled every ``step_mm`` along it."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], int(s[-1] // step_mm) + 1)
    pts = np.stack([np.interp(t, s, line[:, k]) for k in range(3)], 1)
    a = np.diff(pts, axis=0)
    cos = np.sum(a[:-1] * a[1:], axis=1) / (np.linalg.norm(a[:-1], axis=1) * np.linalg.norm(a[1:], axis=1))
    return np.asarray(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


@pytest.mark.parametrize("level", [0.3, 0.4, 0.5])
def test_the_nose_and_lip_colour_edges_are_smooth_curves(level: float) -> None:
    # sampled every mm, the saw-tooth turned by 80..100 deg at each spike; the edges' own curves turn by
    # ~50 deg at most (where the lips' band ends at the mouth corner)
    v, f, c = dog_gen.skin()
    lines = [ln for ln in _iso_lines(v, f, c[:, :3] @ LUMA, level) if len(ln) >= 20]
    assert len(lines) >= 2  # the nose pad's edge and the lips' band
    for line in lines:
        turns = _turns_deg(line, 1.0)
        where = (line.mean(0) - dog_gen.OFFSET).round(0)
        assert turns.max() < 60.0, (where, np.sort(turns)[-5:].round(0))


def _human_lip_lines(level_frac: float) -> list[np.ndarray]:
    """Iso-lines of the human skin's lightness at ``level_frac`` of the way from skin to lip colour, round
    the mouth (head frame; the nostrils, just above, excluded)."""
    v, f, c = human_gen.skin()
    skin, lip = np.array(human_gen.SKIN_RGBA[:3]) @ LUMA, np.array(human_gen.LIP_RGBA[:3]) @ LUMA
    lines = _iso_lines(v, f, c[:, :3] @ LUMA, skin + level_frac * (lip - skin))
    mouth_y = human_gen.MOUTH_Y
    return [
        ln
        for ln in lines
        if len(ln) >= 20 and abs(ln.mean(0)[0]) < 40.0 and abs(ln.mean(0)[1] - mouth_y) < 12.0 and ln.mean(0)[2] > 30.0
    ]


@pytest.mark.parametrize("level_frac", [0.4, 0.5, 0.7, 0.8])
def test_the_human_lip_colour_edges_are_smooth_curves(level_frac: float) -> None:
    # sampled every mm, the old per-vertex lip colour turned by 61..86 deg at the lips' ends (|x| 19..25 mm);
    # the lip weight's own iso-lines (on a fine flat grid) turn by 30..40 deg at these levels
    lines = _human_lip_lines(level_frac)
    assert len(lines) == 2  # the upper and the lower lip (the mouth slit parts them)
    for line in lines:
        turns = _turns_deg(line, 1.0)
        assert turns.max() < 60.0, (line.mean(0).round(0), np.sort(turns)[-5:].round(0))


def test_the_human_lips_keep_their_full_colour_inside() -> None:
    # blending the lip weight softens its edge; it must not wash the lips out
    v, _, c = human_gen.skin()
    core = (np.abs(v[:, 0]) < 16.0) & (np.abs(v[:, 1] - human_gen.MOUTH_Y) < 6.0) & (v[:, 2] > 30.0)
    skin, lip = np.array(human_gen.SKIN_RGBA[:3]) @ LUMA, np.array(human_gen.LIP_RGBA[:3]) @ LUMA
    weight = (skin - c[core, :3] @ LUMA) / (skin - lip)
    assert core.sum() > 20
    assert weight.min() > 0.9
