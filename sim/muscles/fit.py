"""The inverse of the muscle model at the skin anchors: anchor pulls (mm) -> a skin deformation.

Used by the twin (``FaceModel.pose_from_targets``): the servo goals say only how far each anchor is
pulled along its line, and the twin must show a whole face. Method:

1. **Muscle fit.** With L (A x M) = the pull of each anchor per unit contraction of each muscle (the
   line of action dotted with the muscle's rest field at the anchor vertex), solve the bounded, lightly
   regularised least squares  min |L c - p|² + μ² |c|²,  lo <= c <= hi  (the AU table's contraction
   range). The regularised unconstrained solution is precomputed; when it leaves the bounds, a
   non-negative least squares on c - lo runs (``scipy.optimize.nnls``, tens of µs), and BVLS
   (``scipy.optimize.lsq_linear``) only if the upper bound binds too. The face is then the muscle face
   of those contractions, so the twin looks like the muscle face (the same kind of deformation, not a
   blob around each anchor).
2. **Exact anchors.** What the muscles cannot explain (an anchor no muscle pulls along its line, a
   sphincter cap, a contraction bound) is added with a smooth bump per anchor, w(d) = cos(π/2 · d / R)
   within R = the actuator's ``radius_mm`` of the anchor, scaled along the line of action. The bump
   heights come from the small A x A system K s = residual (K_ab = w_b(anchor a) · line_a·line_b), so
   every anchor's projected pull equals its target exactly (when K is regular). With a ``slit`` gate
   (``servoface.sim.muscles.slit``) a bump reaches the far side of a slit only round its ends: the
   upper-lip anchor does not drag the lower lip.

The bump weights are computed on the vertices a k-d tree finds within each anchor's radius
(``servoface.sim.muscles.near``; pass the skin's ``near`` to share its tree), not on every vertex per anchor.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.optimize import lsq_linear, nnls
from servoface.sim.muscles.near import NearVertices
from servoface.sim.muscles.slit import SlitGate

FloatArray = NDArray[np.float64]

REGULARISATION_MM = 0.05  # μ: mm of anchor pull worth one unit of contraction² (small: pulls dominate)


class AnchorFit:
    """Precomputed fit of muscle contractions and anchor bumps for one head's anchors."""

    def __init__(
        self,
        unit_pull_mm: FloatArray,
        bounds: tuple[float, float],
        rest_mm: FloatArray,
        anchor_vertices: Sequence[int] | NDArray[np.int64],
        lines: FloatArray,
        radii_mm: Sequence[float],
        regularisation_mm: float = REGULARISATION_MM,
        slit: SlitGate | None = None,
        near: NearVertices | None = None,
    ) -> None:
        self.unit_pull = np.asarray(unit_pull_mm, dtype=np.float64)  # (A, M)
        n_anchor, n_muscle = self.unit_pull.shape
        self.low, self.high = bounds
        self.mu = regularisation_mm
        self.lines = np.asarray(lines, dtype=np.float64).reshape(n_anchor, 3)
        self.anchor_vertices = np.asarray(anchor_vertices, dtype=np.int64)
        gram = self.unit_pull.T @ self.unit_pull + self.mu**2 * np.eye(n_muscle)
        self._pinv = np.linalg.solve(gram, self.unit_pull.T) if n_muscle else np.zeros((0, n_anchor))
        self._stacked = np.vstack([self.unit_pull, self.mu * np.eye(n_muscle)])
        rest = np.asarray(rest_mm, dtype=np.float64)
        n_vertices = rest.shape[0]
        rows, cols, vals = [], [], []
        if near is None and n_anchor:
            near = NearVertices(rest)
        for a, (vertex, radius) in enumerate(zip(self.anchor_vertices, radii_mm, strict=True)):
            cand = near.within(rest[vertex], radius) if near is not None else np.zeros(0, dtype=np.int64)
            d = np.linalg.norm(rest[cand] - rest[vertex], axis=1)
            inside = d < radius
            idx, d = cand[inside], d[inside]
            weight = np.cos(d / radius * (math.pi / 2))
            if slit is not None and slit.has_slit and slit.on_slit[idx].any():
                weight = weight * slit.gate(int(vertex), idx)
            rows.append(idx)
            cols.append(np.full(idx.size, a))
            vals.append(weight)
        if rows:
            bump = sp.csr_matrix(
                (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                shape=(n_vertices, n_anchor),
            )
        else:
            bump = sp.csr_matrix((n_vertices, 0))
        self.bump: sp.csr_matrix = bump  # (n, A) weights
        at_anchors = bump[self.anchor_vertices].toarray() if n_anchor else np.zeros((0, 0))  # w_b(anchor a)
        self.kernel = at_anchors * (self.lines @ self.lines.T)

    def contractions(self, pulls_mm: FloatArray) -> FloatArray:
        """(M,) contractions whose anchor pulls best match ``pulls_mm`` (A,) within the bounds."""
        p = np.asarray(pulls_mm, dtype=np.float64)
        if self._pinv.shape[0] == 0:
            return np.zeros(0)
        c = self._pinv @ p
        if np.all(c >= self.low - 1e-12) and np.all(c <= self.high + 1e-12):
            return np.clip(c, self.low, self.high)
        rhs = np.concatenate([p, np.zeros(self._pinv.shape[0])])
        # c = low + y with y >= 0: non-negative least squares (fast active set); BVLS only when an upper
        # bound binds as well
        shifted = rhs - self._stacked @ np.full(self._pinv.shape[0], self.low)
        y = nnls(self._stacked, shifted)[0]
        c = self.low + y
        if np.all(c <= self.high + 1e-9):
            return np.asarray(np.minimum(c, self.high), dtype=np.float64)
        result = lsq_linear(self._stacked, rhs, bounds=(self.low, self.high), method="bvls")
        return np.asarray(result.x, dtype=np.float64)

    def bumps(self, residual_mm: FloatArray) -> FloatArray:
        """(n, 3) bump offsets that add ``residual_mm`` (A,) to the anchors' projected pulls."""
        r = np.asarray(residual_mm, dtype=np.float64)
        if r.size == 0 or not np.any(np.abs(r) > 1e-9):
            return np.zeros((self.bump.shape[0], 3))
        try:
            heights = np.linalg.solve(self.kernel, r)
        except np.linalg.LinAlgError:
            heights = np.linalg.lstsq(self.kernel, r, rcond=None)[0]
        return np.asarray(self.bump @ (heights[:, None] * self.lines), dtype=np.float64)
