"""Calibration plots: one PNG per servo with the measured points, the fitted curve, limits and neutral.

matplotlib is imported inside the function with the Agg canvas (no display, no pyplot global state).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from servoface.calibration.errors import CalibrationError
from servoface.calibration.servo import ServoCalibration


def plot_servo(servo: ServoCalibration, path: str | os.PathLike[str], *, warnings: list[str] | None = None) -> Path:
    """Write ``path`` (PNG): target on x, tick on y. Returns the path."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as err:  # optional at import time, required here
        raise CalibrationError("plotting needs matplotlib: pip install matplotlib") from err

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    span = servo.max_target - servo.min_target
    t = np.linspace(servo.min_target - 0.08 * span, servo.max_target + 0.08 * span, 400)
    ticks = servo.curve.forward(t)
    inside = (t >= servo.min_target) & (t <= servo.max_target)

    fig = Figure(figsize=(6.4, 4.4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(t[inside], ticks[inside], color="tab:blue", lw=2, label=f"{servo.curve.kind} curve")
    ax.plot(t[t < servo.min_target], ticks[t < servo.min_target], color="tab:blue", lw=1, ls=":")
    ax.plot(
        t[t > servo.max_target],
        ticks[t > servo.max_target],
        color="tab:blue",
        lw=1,
        ls=":",
        label="beyond limits",
    )
    pts = servo.measured_points
    if pts.size:
        ax.scatter(pts[:, 0], pts[:, 1], color="tab:orange", zorder=3, s=28, label=f"measured ({len(pts)})")
    for tick in (servo.min_tick, servo.max_tick):
        ax.axhline(tick, color="tab:red", lw=0.8, ls="--")
    for target in (servo.min_target, servo.max_target):
        ax.axvline(target, color="tab:red", lw=0.8, ls="--")
    ax.plot([], [], color="tab:red", lw=0.8, ls="--", label="limits")
    ax.scatter(
        [servo.neutral_target],
        [servo.neutral_tick],
        marker="D",
        color="tab:green",
        zorder=4,
        s=40,
        label=f"neutral ({servo.neutral_tick})",
    )
    ax.set_xlabel(f"target ({servo.unit})")
    ax.set_ylabel("goal position (tick)")
    ax.set_title(
        f"{servo.role} (id {servo.servo_id}, {servo.model}): ticks {servo.min_tick}..{servo.max_tick}, "
        f"{servo.min_target:g}..{servo.max_target:g} {servo.unit}",
        fontsize=9,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    if warnings:
        fig.text(0.01, 0.01, "\n".join(w[:110] for w in warnings[:3]), fontsize=6, color="tab:red", va="bottom")
    fig.tight_layout()
    fig.savefig(str(p), format="png")
    return p
