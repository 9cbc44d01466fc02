"""Gaze shifts over time, as a timeline layer that outputs head and eye AUs.

``GazeLayer.look_at(at_s, target_mm)`` schedules a shift; ``look_ahead(at_s)`` returns to straight ahead.
Each shift: the eyes saccade in ``saccade_s`` (0.12 s, minimum-jerk) towards the target, the neck follows
over ``head_move_s`` (0.6 s, minimum-jerk) to the coordinated pose of :func:`solve_look_at`, and while it
does the eyes counter-rotate to stay on the target (the vestibulo-ocular reflex). Everything is a pure
function of time; a shift that starts during another starts from where that one had got to.

Output (the layer's ``sample``) is AU intensities, the AU full scale being the joint limits of
:class:`GazeConfig` (the Face contract's ranges): human AU61/62 eyes left/right, AU63/64 eyes up/down,
AU51/52 head left/right, AU53/54 head up/down, AU55/56 head tilt left/right; dog (signed DFACS) AU12 eyes
left(+)/right(-), AU13 eyes up/down, AU10 head left/right, AU9 head up/down, AU11 head twist.
Joint targets in degrees are available from :meth:`GazeLayer.pose_at`.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from servoface.controller.alive.gaze import (
    GazeConfig,
    GazePose,
    eyes_for_head,
    gaze_config_for,
    solve_look_at,
)
from servoface.controller.errors import TimelineError
from servoface.controller.timeline.easing import min_jerk
from servoface.sim.rig import FaceType


def _split(value: float, pos: str, neg: str) -> dict[str, float]:
    v = max(-1.0, min(1.0, value))
    return {pos: v, neg: 0.0} if v >= 0 else {pos: 0.0, neg: -v}


def _clip1(value: float) -> float:
    return max(-1.0, min(1.0, value))


def angles_to_aus(
    face_type: FaceType,
    cfg: GazeConfig,
    head_yaw_deg: float = 0.0,
    head_pitch_deg: float = 0.0,
    eye_yaw_deg: float = 0.0,
    eye_pitch_deg: float = 0.0,
    head_roll_deg: float = 0.0,
) -> dict[str, float]:
    """Joint angles -> head/eye AUs for a face type (AU 1.0 = the joint limit in ``cfg``)."""
    hy = head_yaw_deg / cfg.neck_limit_yaw_deg
    hp = head_pitch_deg / cfg.neck_limit_pitch_deg
    hr = head_roll_deg / cfg.neck_limit_roll_deg
    ey = eye_yaw_deg / cfg.eye_limit_yaw_deg
    ep = eye_pitch_deg / cfg.eye_limit_pitch_deg
    if face_type == "human":  # each pair as `_split` gives it, in this order
        out: dict[str, float] = {}
        for value, pos, neg in ((hy, "AU51", "AU52"), (hp, "AU53", "AU54"), (hr, "AU55", "AU56"),
                                (ey, "AU61", "AU62"), (ep, "AU63", "AU64")):  # fmt: skip
            v = max(-1.0, min(1.0, value))
            if v >= 0:
                out[pos], out[neg] = v, 0.0
            else:
                out[pos], out[neg] = 0.0, -v
        return out
    if face_type == "dog":
        return {
            "AU10": _clip1(hy),
            "AU9": _clip1(hp),
            "AU11": _clip1(hr),
            "AU12": _clip1(ey),
            "AU13": _clip1(ep),
        }
    raise TimelineError(f"gaze: face type must be 'human' or 'dog', got {face_type!r}")


@dataclass(frozen=True)
class GazeShift:
    at_s: float
    target_mm: tuple[float, float, float] | None  # None = straight ahead


class GazeLayer:
    """Scheduled gaze shifts for one face; a timeline layer (name it "gaze")."""

    uses_below = False

    def __init__(self, face_type: FaceType, config: GazeConfig | None = None) -> None:
        self.face_type = face_type
        self.config = config or gaze_config_for(face_type)
        self._shifts: list[GazeShift] = []
        self._starts: list[float] = []
        self._solutions: list[GazePose] = []
        self._initial: list[GazePose] = []  # the pose each shift starts from
        # shift index -> its settled AUs (both minimum-jerk moves at their end: the same every frame), for
        # the config they were computed with; cleared whenever a shift is scheduled
        self._settled: dict[int, tuple[GazeConfig, dict[str, float]]] = {}

    @property
    def shifts(self) -> tuple[GazeShift, ...]:
        return tuple(self._shifts)

    def look_at(self, at_s: float, target_mm: tuple[float, float, float] | None) -> GazePose:
        """Schedule a shift to ``target_mm`` (head frame, mm) at ``at_s``; returns the final pose."""
        if not (isinstance(at_s, int | float) and math.isfinite(at_s)):
            raise TimelineError(f"gaze: at_s must be a finite time in seconds, got {at_s!r}")
        target: tuple[float, float, float] | None = None
        if target_mm is not None:
            raw = [float(c) for c in target_mm]
            if len(raw) != 3:
                raise TimelineError(f"look_at_mm: expected [x, y, z] in mm, got {target_mm!r}")
            target = (raw[0], raw[1], raw[2])
        if target is not None and not all(math.isfinite(c) for c in target):
            raise TimelineError(f"look_at_mm: expected [x, y, z] in mm, got {target_mm!r}")
        solution = GazePose() if target is None else solve_look_at(np.array(target), self.config)
        index = bisect.bisect_right(self._starts, float(at_s))
        self._settled.clear()
        self._shifts.insert(index, GazeShift(float(at_s), target))
        self._starts.insert(index, float(at_s))
        self._solutions.insert(index, solution)
        del self._initial[index:]
        for i in range(index, len(self._shifts)):
            self._initial.append(GazePose() if i == 0 else self._pose(i - 1, self._starts[i]))
        return solution

    def look_ahead(self, at_s: float) -> GazePose:
        return self.look_at(at_s, None)

    def _pose(self, i: int, t_s: float) -> GazePose:
        cfg, shift, goal, start = self.config, self._shifts[i], self._solutions[i], self._initial[i]
        local = t_s - shift.at_s
        h = min_jerk(local / cfg.head_move_s)
        hy = start.head_yaw_deg + (goal.head_yaw_deg - start.head_yaw_deg) * h
        hp = start.head_pitch_deg + (goal.head_pitch_deg - start.head_pitch_deg) * h
        if shift.target_mm is None:
            want_y = want_p = 0.0
            ok = True
        else:
            want_y, want_p, ok = eyes_for_head(np.array(shift.target_mm), hy, hp, cfg)
        e = min_jerk(local / cfg.saccade_s)
        ey = start.eye_yaw_deg + (want_y - start.eye_yaw_deg) * e
        ep = start.eye_pitch_deg + (want_p - start.eye_pitch_deg) * e
        return GazePose(hy, hp, ey, ep, ok)

    def pose_at(self, t_s: float) -> GazePose:
        """Joint-space gaze at ``t_s`` (neutral before the first shift)."""
        i = bisect.bisect_right(self._starts, t_s) - 1
        return GazePose() if i < 0 else self._pose(i, t_s)

    def sample(self, t_s: float, below: Mapping[str, float] | None = None) -> dict[str, float]:
        i = bisect.bisect_right(self._starts, t_s) - 1
        if i < 0:
            return {}
        cfg = self.config
        local = t_s - self._shifts[i].at_s
        if local / cfg.head_move_s >= 1.0 and local / cfg.saccade_s >= 1.0:  # both easings clamp to 1: settled
            done = self._settled.get(i)
            if done is None or done[0] is not cfg:
                done = (cfg, self._aus(self._pose(i, t_s)))
                self._settled[i] = done
            return dict(done[1])
        return self._aus(self._pose(i, t_s))

    def _aus(self, p: GazePose) -> dict[str, float]:
        return angles_to_aus(
            self.face_type, self.config, p.head_yaw_deg, p.head_pitch_deg, p.eye_yaw_deg, p.eye_pitch_deg
        )
