"""Slits in the skin (the lips): a muscle or an anchor acts on each side of a slit only as far as it
reaches that side along the skin.

Waters' muscle fields are functions of the rest position (muscle-models.md §1), and the two copies of a
slit vertex share their rest position, so every field moved both lips alike and no lip muscle could part
the lips (AU10 lifted the lower lip with the upper one). Kshirsagar et al. (2001; muscle-models.md §5)
keep the lips apart by measuring distance along the surface instead. This module does that only where a
slit makes the difference:

- a field's **source** is the skin vertex it moves most (for an anchor: the anchor's vertex), together
  with any vertex sharing that rest position (a source on the slit itself is on both sides);
- the **detour** of a vertex v is ``g_cut(v) - g_sewn(v)``: its shortest-path distance from the source
  along mesh edges with the slit open, minus the same with the slit sewn shut (every copy of a slit
  vertex merged). It is 0 wherever the slit is not in the way, e.g. everywhere on the source's own lip and
  around the mouth corners, and about the way round the corner on the far lip;
- the field (or anchor bump) at v is scaled by ``gate = k + (1 - k) · cos(π/2 · min(detour / reach_mm, 1))``
  with the coupling k = ``SLIT_COUPLING``: the lips are one orbicularis ring joined at the corners, so about a
  third of a lip muscle's pull still reaches the far lip (the lips part, they do not tear apart). The
  share also keeps the twin's fit well posed: with one anchor per lip, a fully split field let
  lip-tightening cancel a raised upper lip and a lowered lower lip at the anchors (fidelity > 1 mm).

Sphincters are not gated: they straddle the slit by design (orbicularis oris closes both lips). A skin
without duplicated vertices has no slit, and every gate is 1.

Cost: the shortest paths are searched on the part of the skin a path within the search limit can reach
(a path of length L stays within L of its source: the vertices in that ball, from a k-d tree), and each
search stops at the distance the gate can still depend on: the sewn search first at 1.5x the farthest
gated vertex plus twice the reach (again at the full limit if a gated vertex is not reached), the cut
search at the farthest sewn distance plus the reach (a vertex whose cut path is longer than that gets the
coupling share whatever its exact length). Every distance a gate reads is the one the search over the
whole skin up to the full limit finds (`tests/sim/test_muscle_build_equivalence.py`), so the build grows
with the vertices near each source instead of with every vertex per source.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import dijkstra
from servoface.sim.muscles.near import NearVertices

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

SLIT_REACH_MM = 8.0  # a detour of this much along the skin and only the coupling share crosses
SLIT_COUPLING = 0.35  # share of a field that still reaches the far lip: both lips are one orbicularis ring
BALL_MARGIN_MM = 1.0  # the ball of a search: its limit plus this (slit twins sit within 2e-6 mm of each other)


class SlitGate:
    """The slits of one rest skin and the detour gates of sources on it."""

    def __init__(
        self,
        rest_mm: FloatArray,
        faces: NDArray[np.integer],
        reach_mm: float = SLIT_REACH_MM,
        coupling: float = SLIT_COUPLING,
    ) -> None:
        rest = np.asarray(rest_mm, dtype=np.float64)
        tri = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        self.n_vertices = int(rest.shape[0])
        self._rest = rest
        self.reach_mm = float(reach_mm)
        self.coupling = float(coupling)
        self._memo: dict[tuple[bytes, bytes], FloatArray] = {}
        inverse, counts = row_groups(np.round(rest, 6))
        self.representative: IntArray = np.asarray(inverse, dtype=np.int64)  # vertex -> merged id
        self.on_slit = np.asarray(counts[inverse] > 1, dtype=bool)
        self.has_slit = bool(self.on_slit.any()) and tri.size > 0
        if not self.has_slit:
            return
        a = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2]])
        b = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0]])
        length = np.linalg.norm(rest[a] - rest[b], axis=1)
        keep = length > 0.0
        a, b, length = a[keep], b[keep], length[keep]
        n = self.n_vertices
        self._cut = sp.csr_matrix((length, (a, b)), shape=(n, n))
        self._cut = self._cut.maximum(self._cut.T)
        m = int(inverse.max()) + 1
        sewn = sp.csr_matrix((length, (inverse[a], inverse[b])), shape=(m, m))
        self._sewn = sewn.maximum(sewn.T)
        self.near = NearVertices(rest)

    def gate(self, source: int | Sequence[int] | IntArray, vertices: IntArray | None = None) -> FloatArray:
        """(k,) gate in [0, 1] of a field with the given source vertex (or vertices) at ``vertices``
        (default: every vertex)."""
        idx = np.arange(self.n_vertices) if vertices is None else np.asarray(vertices, dtype=np.int64)
        if not self.has_slit:
            return np.ones(idx.size)
        src = np.atleast_1d(np.asarray(source, dtype=np.int64))
        key = (src.tobytes(), idx.tobytes())
        if key not in self._memo:
            self._memo[key] = self._gate(src, idx)
        return self._memo[key].copy()

    def _gate(self, src: IntArray, idx: IntArray) -> FloatArray:
        src = np.nonzero(np.isin(self.representative, self.representative[src]))[0]  # with its twins
        # paths along the skin stay within a few times the straight distance: search no farther
        reach = 3.0 * float(np.max(np.linalg.norm(self._rest[idx] - self._rest[src[0]], axis=1), initial=0.0))
        limit = reach + 2.0 * self.reach_mm
        roots = np.unique(self.representative[src])
        merged = self.representative[idx]
        first = min(limit, 0.5 * reach + 2.0 * self.reach_mm)
        sewn = self._distances(self._sewn, roots, merged, src[0], first, merged=True)
        if first < limit and not np.all(np.isfinite(sewn)):
            sewn = self._distances(self._sewn, roots, merged, src[0], limit, merged=True)
        finite = sewn[np.isfinite(sewn)]
        # a cut path longer than the sewn one plus the reach gives the coupling share whatever its length
        cut_limit = min(limit, float(np.max(finite, initial=0.0)) + self.reach_mm + BALL_MARGIN_MM)
        cut = self._distances(self._cut, src, idx, src[0], cut_limit, merged=False)
        detour = np.where(np.isfinite(cut) & np.isfinite(sewn), cut - sewn, np.inf)
        detour = np.where(np.isfinite(sewn) & ~np.isfinite(cut), np.inf, detour)
        detour = np.where(~np.isfinite(sewn), 0.0, detour)  # unreachable either way: not the slit's doing
        out = np.cos(np.clip(detour / self.reach_mm, 0.0, 1.0) * (np.pi / 2))
        out = np.where(detour >= self.reach_mm, 0.0, out)
        return np.asarray(self.coupling + (1.0 - self.coupling) * out, dtype=np.float64)

    def _distances(
        self, graph: sp.csr_matrix, sources: IntArray, targets: IntArray, centre: int, limit: float, *, merged: bool
    ) -> FloatArray:
        """Shortest distances (targets,) from the nearest of ``sources`` in ``graph`` (the cut skin, or the
        sewn one with ``merged``: node ids are merged vertex ids), inf beyond ``limit``: the same values as
        ``dijkstra(graph, indices=sources, min_only=True, limit=limit)[targets]``, searched on the nodes
        within ``limit`` of vertex ``centre`` only."""
        ball = self.near.within(self._rest[centre], limit + BALL_MARGIN_MM)
        nodes = np.unique(self.representative[ball]) if merged else ball
        local = graph[nodes][:, nodes]
        dist = np.asarray(dijkstra(local, indices=np.searchsorted(nodes, sources), min_only=True, limit=limit))
        at = np.minimum(np.searchsorted(nodes, targets), nodes.size - 1)
        return np.where(nodes[at] == targets, dist[at], np.inf)


def row_groups(rows: FloatArray) -> tuple[IntArray, IntArray]:
    """``np.unique(rows, axis=0, return_inverse=True, return_counts=True)[1:]`` (the group of each row, the
    groups numbered in the rows' lexicographic order, and each group's size) by one lexsort of the columns
    (numpy's row unique sorts a structured view, ~5x slower at 80k rows)."""
    n = int(rows.shape[0])
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    order = np.lexsort(rows.T[::-1])
    ranked = rows[order]
    new = np.ones(n, dtype=bool)
    new[1:] = np.any(ranked[1:] != ranked[:-1], axis=1)
    group = np.cumsum(new) - 1
    inverse = np.empty(n, dtype=np.int64)
    inverse[order] = group
    return inverse, np.bincount(group).astype(np.int64)


_GATES: dict[tuple[str, float, float], SlitGate] = {}
_GATES_MAX = 8


def forget_shared_gates() -> None:
    """Drop every shared ``SlitGate``: the next ``FaceModel`` of any mesh builds its own (a cold build, as
    ``servoface bench scale`` times it)."""
    _GATES.clear()


def slit_gate(
    rest_mm: FloatArray, faces: NDArray[np.integer], reach_mm: float = SLIT_REACH_MM, coupling: float = SLIT_COUPLING
) -> SlitGate:
    """A ``SlitGate`` for this skin, shared by every face model of the same mesh (its shortest paths are
    the costly part of building a ``FaceModel``)."""
    rest = np.ascontiguousarray(rest_mm, dtype=np.float64)
    tri = np.ascontiguousarray(faces, dtype=np.int64)
    digest = hashlib.sha1(rest.tobytes() + b"|" + tri.tobytes()).hexdigest()
    key = (digest, float(reach_mm), float(coupling))
    gate = _GATES.get(key)
    if gate is None:
        if len(_GATES) >= _GATES_MAX:
            _GATES.pop(next(iter(_GATES)))
        gate = _GATES[key] = SlitGate(rest, tri, reach_mm, coupling)
    return gate
