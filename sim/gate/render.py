"""The twin's verdict as a picture: the requested face next to the gated face, with the reasons.

Uses RENDER's helpers (`servoface.sim.render.twin.render_target_vs_gated`); headless through EGL like every render.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.verdict import Verdict

Image = NDArray[np.uint8]


def verdict_targets(gate: Any, verdict: Verdict) -> tuple[dict[str, float], dict[str, float]]:
    """(requested, gated) actuator targets (role -> deg / mm) as the twin sees them."""
    requested = verdict.requested_tick or verdict.goals_tick
    return gate.twin_pose(requested)[2], gate.twin_pose(verdict.goals_tick)[2]


def render_verdict(
    head: Any,
    requested_pose: Mapping[str, float] | Any,
    gated_pose: Mapping[str, float] | Any,
    verdict: Verdict,
    renderer: Any | None = None,
    size_px: tuple[int, int] = (480, 480),
    max_reasons: int = 6,
) -> Image:
    """Side by side: the requested face and the gated face (each a `HeadPose` or actuator targets),
    labelled, with the verdict and its reasons printed underneath. (H, W, 3) uint8."""
    from PIL import Image as PILImage
    from PIL import ImageDraw, ImageFont
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.twin import render_target_vs_gated

    r = renderer or HeadRenderer(*size_px)
    pair = render_target_vs_gated(
        r,
        head,
        requested_pose,
        gated_pose,
        labels=("requested", f"gated: {verdict.kind} (step {verdict.step_fraction:.2f})"),
    )
    h, w = pair.shape[:2]
    lines = [f"verdict {verdict.kind}; checks: {', '.join(verdict.checks) or 'none'}"]
    for reason in verdict.reasons()[:max_reasons]:
        lines += textwrap.wrap(reason, width=max(40, w // 8)) or [""]
    if len(verdict.findings) > max_reasons:
        lines.append(f"... and {len(verdict.findings) - max_reasons} more")
    line_px = 16
    canvas = PILImage.new("RGB", (w, h + line_px * len(lines) + 8), (24, 24, 24))
    canvas.paste(PILImage.fromarray(pair), (0, 0))
    draw = ImageDraw.Draw(canvas)
    font = ImageFont.load_default()
    for i, line in enumerate(lines):
        draw.text((6, h + 4 + i * line_px), line, fill=(235, 235, 235), font=font)
    return np.asarray(canvas, dtype=np.uint8)
