"""Per-AU smoothing of tracker data: the One-Euro filter (Casiez, Roussel & Vogel, CHI 2012).

Tracker intensities jitter frame to frame (OpenFace's per-AU SVRs, MediaPipe's blendshapes; facs-human.md
§5). A One-Euro filter is an exponential smoother whose cutoff rises with the signal's speed: slow
changes are smoothed hard (no jitter at rest), fast ones pass with little lag. Each output is a convex
combination of the input and the previous output, so it never leaves the range of its inputs (an AU in
0..1 stays in 0..1). Times are passed in (``t_s``), so tests drive it with a fake clock.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass


def _alpha(cutoff_hz: float, dt_s: float) -> float:
    tau = 1.0 / (2.0 * math.pi * cutoff_hz)
    return 1.0 / (1.0 + tau / dt_s)


@dataclass
class OneEuroFilter:
    """One channel. ``min_cutoff_hz``: smoothing at rest (lower = smoother); ``beta``: how fast the cutoff
    rises with speed (higher = less lag on fast moves); ``d_cutoff_hz``: the speed estimate's cutoff."""

    min_cutoff_hz: float = 1.5
    beta: float = 0.5
    d_cutoff_hz: float = 1.0
    _x: float | None = None
    _dx: float = 0.0
    _t: float = 0.0

    def __call__(self, x: float, t_s: float) -> float:
        if self._x is None:
            self._x, self._dx, self._t = x, 0.0, t_s
            return x
        dt = t_s - self._t
        if dt <= 0.0:  # same instant (or a clock step back): keep the last output
            return self._x
        dx = (x - self._x) / dt
        self._dx += _alpha(self.d_cutoff_hz, dt) * (dx - self._dx)
        cutoff = self.min_cutoff_hz + self.beta * abs(self._dx)
        self._x += _alpha(cutoff, dt) * (x - self._x)
        self._t = t_s
        return self._x

    def reset(self) -> None:
        self._x = None
        self._dx = 0.0


class AUSmoother:
    """One-Euro filters per AU name; an AU missing from a frame is filtered towards 0 (neutral)."""

    def __init__(self, min_cutoff_hz: float = 1.5, beta: float = 0.5, d_cutoff_hz: float = 1.0) -> None:
        for name, value in (("min_cutoff_hz", min_cutoff_hz), ("beta", beta), ("d_cutoff_hz", d_cutoff_hz)):
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not math.isfinite(value)
                or value < 0
                or (name != "beta" and value == 0)
            ):
                raise ValueError(f"smoothing {name}: expected a finite number > 0 (beta >= 0), got {value!r}")
        self.params = (float(min_cutoff_hz), float(beta), float(d_cutoff_hz))
        self._filters: dict[str, OneEuroFilter] = {}

    def __call__(self, aus: Mapping[str, float], t_s: float) -> dict[str, float]:
        out: dict[str, float] = {}
        for name in set(aus) | set(self._filters):
            f = self._filters.get(name)
            if f is None:
                f = self._filters[name] = OneEuroFilter(*self.params)
                if name not in aus:
                    continue
            out[name] = f(aus.get(name, 0.0), t_s)
        return out

    def reset(self) -> None:
        self._filters.clear()
