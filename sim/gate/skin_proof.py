"""Skin the joints alone bend, proven inside the strain limits over the whole joint box (so not measured).

The skin no anchor pull moves keeps its rest offsets; where it is blended between two joints (a skull and
a jaw) its shape follows the joints between them alone. When no single servo decides those joints (the
dog's jaw and jaw_lateral: no per-tick table, `skin_static`), an edge or a triangle of that skin is left
out of the per-frame strain measure if it is *proven* within the limits for every pose of those joints
inside their limits (the twin clamps joint angles to them): edge stretch below ``max_stretch`` and above
``min_compression``, and a triangle never flipped. Left-out edges and triangles then cannot change a
verdict or a finding: a finding reports the largest stretch, smallest compression or number of flips,
which (beyond a limit) come from the measured ones.

The proof: in the outer joint's frame (strain is blind to a common rigid motion), a vertex with weight
``w`` on the inner joint sits at ``(1 - w) x + w T(q) x``, ``T`` the product of the joints' rest-frame
transforms (rotations about pivots). On a grid over the joint box every edge vector and triangle is
evaluated exactly (float64); between nodes a joint is at most half a grid step from the nearest node, and a
point ``y`` moves by at most ``sum_k dθ_k · ρ_k(y)`` (``ρ_k``: its distance from joint k's pivot, plus the
pivot-to-pivot distances down the chain). An edge ``(i, j)`` is ``(1 - w_i) x_i - (1 - w_j) x_j +
(w_i - w_j) T x_i + w_j R (x_i - x_j)``: it moves by at most ``|w_i - w_j| · motion(x_i) + w_j · sum dθ ·
|x_i - x_j|``. Bounds get a relative margin of 1e-4 beyond float32's rounding of the measure.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.strain import SkinTwin, StrainLimits

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

GRID_STEP_DEG = 4.0
_MAX_NODES = 4096
_MARGIN = 1e-4  # relative, far above float32 rounding (~1e-6) of the per-frame measure
_CHUNK = 64


def _extra_joints(skin: SkinTwin, tree: JointTree) -> tuple[int, list[int]] | None:
    """(column of the inner slot in the skin's used weights, the joints between the outer and the inner
    slot, parent first) when the skin hangs from exactly two slots, one below the other; else None."""
    used = [int(u) for u in skin._used]
    if len(used) != 2:
        return None
    base = len(tree.names)
    chains = [[] if u == base else tree.chain(tree.names[u]) for u in used]
    for inner in (0, 1):
        outer = 1 - inner
        if set(chains[outer]) <= set(chains[inner]) and len(chains[inner]) > len(chains[outer]):
            extra = [j for j in reversed(chains[inner]) if j not in set(chains[outer])]
            return inner, extra
    return None


def _grid(tree: JointTree, joints: list[int]) -> tuple[FloatArray, FloatArray]:
    """(nodes (N, m) deg, half step (m,) rad) over the joints' limits."""
    lo, hi = tree.lower_deg[joints], tree.upper_deg[joints]
    counts = np.maximum(1, np.ceil((hi - lo) / GRID_STEP_DEG).astype(np.int64) + 1)
    while int(np.prod(counts)) > _MAX_NODES:
        counts = np.maximum(1, (counts + 1) // 2)
    axes = [np.linspace(a, b, int(c)) if c > 1 else np.array([a]) for a, b, c in zip(lo, hi, counts, strict=True)]
    nodes = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
    half = np.deg2rad(np.where(counts > 1, (hi - lo) / np.maximum(counts - 1, 1), 0.0)) / 2.0
    return nodes, half


def proven_static(skin: SkinTwin, tree: JointTree, limits: StrainLimits) -> tuple[BoolArray, BoolArray] | None:
    """(edges, faces) masks over the skin's active edges / faces (`SkinTwin.n_active_edges` / `_faces`)
    proven inside ``limits`` for every pose (see the module docstring); None when the skin does not hang
    from two joints one below the other."""
    found = _extra_joints(skin, tree)
    if found is None:
        return None
    inner, joints = found
    mv = skin.movable[skin._v]
    static_e = ~mv[skin._edges].any(axis=1)
    static_f = ~mv[skin._faces].any(axis=1)
    x = skin._rest_v  # (nv, 3) rest positions of the active vertices
    w_all = skin._w  # (nv, 2) weights on the two used slots
    sums_one = np.abs(w_all.sum(axis=1) - 1.0) <= 1e-12
    w = np.clip(w_all[:, inner], 0.0, 1.0)
    nodes, half = _grid(tree, joints)
    pivots = tree.pivot_mm[joints]
    # rho[k, v]: distance of vertex v from joint k's pivot plus the pivot steps down the chain
    steps = np.r_[np.linalg.norm(np.diff(pivots, axis=0), axis=1), 0.0]
    tail = np.cumsum(steps[::-1])[::-1]  # sum of pivot steps from joint k to the last joint
    rho = np.linalg.norm(x - pivots[-1], axis=1)[None, :] + tail[:, None]
    motion = half @ rho  # (nv,) max motion of a vertex from its nearest node
    turn = float(half.sum())  # max rotation angle from the nearest node (rad)
    edge_ok = np.zeros(len(skin._edges), dtype=bool)
    face_ok = np.zeros(len(skin._faces), dtype=bool)
    e = skin._edges[static_e & sums_one[skin._edges].all(axis=1)]
    f = skin._faces[static_f & sums_one[skin._faces].all(axis=1)]
    e_idx = np.flatnonzero(static_e & sums_one[skin._edges].all(axis=1))
    f_idx = np.flatnonzero(static_f & sums_one[skin._faces].all(axis=1))
    if len(e_idx) == 0 and len(f_idx) == 0:
        return edge_ok, face_ok
    # only the vertices of those edges and faces, renumbered
    keep = np.unique(np.concatenate([e.ravel(), f.ravel()]))
    remap = np.full(len(x), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    x, w, motion, e, f = x[keep], w[keep], motion[keep], remap[e], remap[f]
    i, j = e[:, 0], e[:, 1]
    rest_len = np.linalg.norm(x[i] - x[j], axis=1)
    bound_e = np.abs(w[i] - w[j]) * motion[i] + w[j] * turn * rest_len

    def vec_bound(a: NDArray[np.int64], b: NDArray[np.int64]) -> FloatArray:
        """Motion bound of the vector from vertex b to vertex a."""
        return np.asarray(np.abs(w[a] - w[b]) * motion[a] + w[b] * turn * np.linalg.norm(x[a] - x[b], axis=1))

    f0, f1, f2 = f[:, 0], f[:, 1], f[:, 2]
    bu, bw = vec_bound(f1, f0), vec_bound(f2, f0)
    wf = w[f].mean(axis=1)
    n_rest = skin._rest_normal[f_idx]
    n_len = np.linalg.norm(n_rest, axis=1)
    be = wf * turn * n_len  # bound on the carried normal's change
    hi_ok = np.ones(len(e_idx), dtype=bool)
    lo_ok = np.ones(len(e_idx), dtype=bool)
    flip_ok = np.ones(len(f_idx), dtype=bool)
    smax = limits.max_stretch * (1.0 - _MARGIN)
    cmin = limits.min_compression * (1.0 + _MARGIN)
    for start in range(0, len(nodes), _CHUNK):
        q = np.zeros((len(nodes[start : start + _CHUNK]), len(tree.names)))
        q[:, joints] = nodes[start : start + _CHUNK]
        loc = tree.local(q[:, joints], joints)  # (c, m, 4, 4)
        t = loc[:, 0]
        for k in range(1, len(joints)):
            t = t @ loc[:, k]
        rot, shift = t[:, :3, :3], t[:, :3, 3]
        moved = np.einsum("cij,vj->cvi", rot, x) + shift[:, None, :]  # (c, nv, 3): T x
        p = (1.0 - w)[None, :, None] * x[None] + w[None, :, None] * moved
        d = np.linalg.norm(p[:, i] - p[:, j], axis=-1)  # (c, ne)
        hi_ok &= np.all(d + bound_e <= smax * rest_len, axis=0)
        lo_ok &= np.all(d - bound_e >= cmin * rest_len, axis=0)
        u = p[:, f1] - p[:, f0]
        v = p[:, f2] - p[:, f0]
        c = np.cross(u, v)
        carried = (1.0 - wf)[None, :, None] * n_rest[None] + wf[None, :, None] * np.einsum("cij,fj->cfi", rot, n_rest)
        g = np.einsum("cfi,cfi->cf", c, carried)
        u_len, v_len = np.linalg.norm(u, axis=-1), np.linalg.norm(v, axis=-1)
        bc = bu * (v_len + bw) + u_len * bw
        c_len, e_len = np.linalg.norm(c, axis=-1), np.linalg.norm(carried, axis=-1)
        low = g - (bc * (e_len + be) + c_len * be)
        flip_ok &= np.all(low > _MARGIN * (c_len + bc) * (e_len + be), axis=0)
    edge_ok[e_idx] = hi_ok & lo_ok
    face_ok[f_idx] = flip_ok
    return edge_ok, face_ok
