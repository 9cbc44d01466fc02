"""A recorded sequence of AU frames (from a file) that plays as a source: ``.sample(t_s) -> AUFrame``.

Times are shifted so the first frame is at 0 s. Between two frames the AUs are interpolated linearly
(``interpolate=True``, default: smooth playback of a 30 fps file at a 50 Hz loop) or held; before the first
frame the first one holds, after the last the last one holds. Plugs into
``servoface.controller.performance.play_timeline(pipeline, recording, recording.duration_s)``.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence

from servoface.controller.frame import AUFrame
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.report import InputReport
from servoface.sim.rig import FaceType


class Recording:
    """Frames with increasing times (0-based), sampled by time."""

    def __init__(
        self,
        frames: Sequence[AUFrame],
        face_type: FaceType,
        *,
        interpolate: bool = True,
        source: str = "",
        report: InputReport | None = None,
    ) -> None:
        if not frames:
            raise InputError(f"{source or 'recording'}: no frames")
        t0 = frames[0].t_s
        times = [f.t_s - t0 for f in frames]
        if any(b < a for a, b in zip(times, times[1:], strict=False)):
            raise InputError(f"{source or 'recording'}: frame times must not decrease")
        self.face_type = face_type
        self.frames = [f.with_time(t) for f, t in zip(frames, times, strict=True)]
        self.times_s = times
        self.interpolate = interpolate
        self.source = source
        self.report = report or InputReport(source, rows=len(frames))

    @property
    def duration_s(self) -> float:
        return self.times_s[-1]

    def __len__(self) -> int:
        return len(self.frames)

    def sample(self, t_s: float) -> AUFrame:
        i = bisect.bisect_right(self.times_s, t_s)
        if i == 0:
            return self.frames[0].with_time(t_s)
        if i >= len(self.frames):
            return self.frames[-1].with_time(t_s)
        a, b = self.frames[i - 1], self.frames[i]
        if not self.interpolate or b.t_s <= a.t_s:
            return a.with_time(t_s)
        w = (t_s - a.t_s) / (b.t_s - a.t_s)
        names = set(a.aus) | set(b.aus)
        aus = {n: (1 - w) * a.aus.get(n, 0.0) + w * b.aus.get(n, 0.0) for n in names}
        lo, hi = (0.0, 1.0) if self.face_type == "human" else (-1.0, 1.0)
        return AUFrame(t_s, {n: min(hi, max(lo, v)) for n, v in aus.items()}, self.face_type)


def frames_with_policy(
    rows: Sequence[tuple[float, dict[str, float] | None]],
    face_type: FaceType,
    *,
    lost: str = "hold",
    decay_s: float = 0.5,
    allowed: frozenset[str] | None = None,
) -> tuple[list[AUFrame], int]:
    """AU frames from (t_s, aus or None) rows; None = the tracker lost the face on that row.

    Policy for lost rows: ``"hold"`` keeps the last good AUs; ``"neutral"`` eases them linearly to neutral
    (all 0) over ``decay_s`` after the last good row. Lost rows before the first good one are neutral.
    Returns the frames and the number of rows the policy filled in.
    """
    if lost not in ("hold", "neutral"):
        raise InputError(f"lost: expected 'hold' or 'neutral', got {lost!r}")
    if not decay_s > 0:
        raise InputError(f"decay_s: expected > 0 s, got {decay_s!r}")
    frames: list[AUFrame] = []
    last: dict[str, float] = {}
    last_t: float | None = None
    filled = 0
    for t_s, aus in rows:
        if aus is not None:
            last, last_t = aus, t_s
            frames.append(AUFrame(t_s, aus, face_type, allowed=allowed))
            continue
        filled += 1
        if lost == "hold" or last_t is None:
            frames.append(AUFrame(t_s, last, face_type, allowed=allowed))
        else:
            k = max(0.0, 1.0 - (t_s - last_t) / decay_s)
            frames.append(AUFrame(t_s, {n: v * k for n, v in last.items()}, face_type, allowed=allowed))
    return frames, filled
