"""A smooth opening in a parametric skin: its rim laid on a curve instead of a grid's stair-step.

An opening (an eye) is cut into a skin grid by dropping the quads inside it; the boundary left behind runs
along grid lines, a saw-tooth that a render shows as a jagged edge. `fit_rim` moves the boundary's vertices
onto the intended curve, in the skin's own parameters (so they stay exactly on the skin surface), spread
evenly along it, and `relax_band` evens out the vertices just outside so the rim's triangles keep their
shape; `smooth_opening` does both for an opening and its mirror twin. `boundary_loop` orders an opening's
boundary; `turning_deg` measures how smooth a loop is.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from servoface.sim.heads.mesh_tools import F64, I64

Surface = Callable[[F64, F64], F64]  # (s, t) params (same shape) -> points (..., 3)
Local = Callable[[F64], F64]  # points (..., 3) -> (..., 2) coordinates where the rim is the unit circle

_SAMPLES = 1440  # points on the curve when measuring it
_GAP_SMOOTHING = 12  # passes of a [1, 2, 1] / 4 filter over the gaps between rim vertices


def boundary_loop(faces: I64, near: NDArray[np.bool_]) -> I64:
    """The closed loop of open edges (used by one face) whose two ends are both ``near``, as ordered vertex
    ids (ValueError when they do not form exactly one simple loop)."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    edges = uniq[counts == 1]
    edges = edges[near[edges].all(1)]
    nxt: dict[int, list[int]] = {}
    for a, b in edges.tolist():
        nxt.setdefault(a, []).append(b)
        nxt.setdefault(b, []).append(a)
    if not nxt or any(len(n) != 2 for n in nxt.values()):
        raise ValueError("the opening's boundary is not one simple loop")
    start = min(nxt)
    loop, prev = [start], -1
    while True:
        cur = loop[-1]
        cand = next(n for n in nxt[cur] if n != prev)
        prev = cur
        if cand == start:
            break
        loop.append(cand)
    if len(loop) != len(nxt):
        raise ValueError("the opening's boundary is more than one loop")
    return np.asarray(loop, dtype=np.int64)


def swap_ear_diagonals(faces: I64, n_grid: int, keep: NDArray[np.bool_]) -> I64:
    """Faces with the diagonal swapped in each kept grid quad (faces 2q and 2q + 1) of which one triangle
    would have two edges on the boundary left by dropping the faces not in ``keep``: where two cut-away
    neighbours meet at a corner of the quad, the diagonal then runs through that corner, so no triangle has
    all three corners on the rim (laid on a curve, such an ear folds over the opening). Orientation is kept;
    deciding per quad gives mirror-image grids mirror-image diagonals."""
    kept = faces[keep]
    e = np.sort(np.concatenate([kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    open_edges = {tuple(x) for x in uniq[counts == 1].tolist()}
    out = faces.copy()
    for q in range(n_grid // 2):
        pair = faces[2 * q : 2 * q + 2]
        if not keep[2 * q : 2 * q + 2].all():
            continue
        n_open = [sum(tuple(sorted((int(t[i]), int(t[(i + 1) % 3])))) in open_edges for i in range(3)) for t in pair]
        if max(n_open) < 2:
            continue
        t0, t1 = pair.tolist()
        o0 = next(v for v in t0 if v not in t1)
        o1 = next(v for v in t1 if v not in t0)
        k = t0.index(o0)
        s1, s2 = t0[(k + 1) % 3], t0[(k + 2) % 3]
        out[2 * q], out[2 * q + 1] = (o0, s1, o1), (o1, s2, o0)
    return out


def turning_deg(points: F64) -> F64:
    """(k,) the angle between each closed loop's edge (k, 3 points) and the next one, degrees."""
    a = np.roll(points, -1, axis=0) - points
    b = np.roll(a, -1, axis=0)
    cos = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return np.asarray(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), dtype=np.float64)


def _solve(surface: Surface, local: Local, target: F64, guess: F64, steps: F64) -> F64:
    """Params (m, 2) where ``local(surface(p))`` = ``target`` (m, 2), by Newton from ``guess``; ``steps``
    (2,) are the finite-difference steps of the two params."""
    p = guess.copy()
    for _ in range(30):
        f = local(surface(p[:, 0], p[:, 1])) - target
        jac = np.empty((len(p), 2, 2))
        for k in range(2):
            d = np.zeros(2)
            d[k] = steps[k]
            hi, lo = p + d, p - d
            jac[:, :, k] = (local(surface(hi[:, 0], hi[:, 1])) - local(surface(lo[:, 0], lo[:, 1]))) / (2 * steps[k])
        p = p - np.linalg.solve(jac, f[..., None])[..., 0]
        if float(np.abs(f).max()) < 1e-12:
            break
    res = float(np.abs(local(surface(p[:, 0], p[:, 1])) - target).max())
    if res > 1e-6:
        raise ValueError(f"cannot lay the rim on its curve (residual {res:.2g})")
    return p


def fit_rim(params: F64, surface: Surface, local: Local, steps: F64) -> F64:
    """New params (k, 2) for a loop of rim vertices at ``params`` (k, 2; in loop order, going once round the
    opening): on the curve ``|local(surface(p))| = 1``, in the same cyclic order, with the gaps between them
    smoothed along it (arc length) and phased to move them least."""
    q = local(surface(params[:, 0], params[:, 1]))
    ang = np.unwrap(np.arctan2(q[:, 1], q[:, 0]))
    sense = 1.0 if ang[-1] > ang[0] else -1.0
    # the curve, densely: each sample starts from the rim vertex nearest in angle
    theta = ang[0] + sense * np.linspace(0.0, 2.0 * np.pi, _SAMPLES, endpoint=False)
    gap = np.abs(((theta[:, None] - ang[None, :]) + np.pi) % (2.0 * np.pi) - np.pi)
    guess = params[np.argmin(gap, axis=1)]
    circle = np.stack([np.cos(theta), np.sin(theta)], 1)
    dense = _solve(surface, local, circle, guess, steps)
    pts = surface(dense[:, 0], dense[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1))])
    total = float(cum[-1])
    # where the vertices are now along the curve (by their angle); the stair-step spaces them unevenly, and
    # may even step back: smooth the gaps between them (keeping their sum, one turn), so the spacing follows
    # the grid's density but varies smoothly, and phase the result to move them least
    at = np.interp((sense * (ang - ang[0])) % (2.0 * np.pi), np.linspace(0.0, 2.0 * np.pi, _SAMPLES + 1), cum)
    gaps = (np.roll(at, -1) - at + 0.5 * total) % total - 0.5 * total
    gaps *= total / gaps.sum()
    for _ in range(_GAP_SMOOTHING):
        gaps = 0.25 * np.roll(gaps, 1) + 0.5 * gaps + 0.25 * np.roll(gaps, -1)
    if float(gaps.min()) <= 0.0:
        raise ValueError("the opening's rim vertices do not go round it in order")
    even = np.concatenate([[0.0], np.cumsum(gaps[:-1])])
    phase = np.angle(np.mean(np.exp(2j * np.pi * (at - even) / total))) / (2.0 * np.pi) * total
    want = (even + phase) % total
    closed = np.concatenate([dense, dense[:1]])
    idx = np.clip(np.searchsorted(cum, want, side="right") - 1, 0, _SAMPLES - 1)
    w = ((want - cum[idx]) / (cum[idx + 1] - cum[idx]))[:, None]
    guess = (1.0 - w) * closed[idx] + w * closed[idx + 1]
    # exactly on the curve at the interpolated angle
    t_want = theta[0] + sense * 2.0 * np.pi * np.interp(want, cum, np.linspace(0.0, 1.0, _SAMPLES + 1))
    return _solve(surface, local, np.stack([np.cos(t_want), np.sin(t_want)], 1), guess, steps)


def relax_band(params: F64, faces: I64, fixed: NDArray[np.bool_], band: NDArray[np.bool_], rounds: int) -> F64:
    """Params (n, 2) with the ``band`` vertices (not ``fixed``) moved ``rounds`` times halfway to the mean of
    their edge neighbours (umbrella smoothing in parameter space; a regular grid stays as it is)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    e = np.concatenate([e, e[:, ::-1]])
    move = band & ~fixed
    out = params.copy()
    deg = np.bincount(e[:, 0], minlength=len(params)).astype(np.float64)
    for _ in range(rounds):
        acc = np.zeros_like(out)
        np.add.at(acc, e[:, 0], out[e[:, 1]])
        mean = acc / np.maximum(deg, 1.0)[:, None]
        out[move] = 0.5 * out[move] + 0.5 * mean[move]
    return out


def smooth_opening(
    params: F64,
    faces: I64,
    near: NDArray[np.bool_],
    surface: Surface,
    local: Local,
    steps: F64,
    mirror: tuple[I64, F64],
) -> F64:
    """New params (n, 2) of a grid's n vertices (``faces`` may also use ids >= n, left alone): the opening's
    rim (the open loop among the ``near`` vertices) fitted to its curve (`fit_rim`), the two rings of
    vertices outside it relaxed (`relax_band`), and all of them copied onto the twin opening: vertex
    ``mirror[0][i]`` gets the params of i times ``mirror[1]`` (2,)."""
    n = len(params)
    grid = faces[(faces < n).all(1)]
    rim = boundary_loop(grid, near)
    out = params.copy()
    out[rim] = fit_rim(params[rim], surface, local, steps)
    ring1 = np.setdiff1d(grid[np.isin(grid, rim).any(1)], rim)
    band = np.setdiff1d(grid[np.isin(grid, ring1).any(1)], rim)
    fixed, moving = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    fixed[rim], moving[band] = True, True
    out = relax_band(out, grid, fixed, moving, rounds=4)
    changed = np.concatenate([rim, band])
    out[mirror[0][changed]] = out[changed] * mirror[1]
    return out
