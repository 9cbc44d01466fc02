"""What a track plays: sources, each sampled by the loop thread at the frame's service time.

A source is started on the loop thread (``begin(t0_s, from_pose)``: the time it takes over and the pose
its track had then), then sampled every frame (``sample(t_s, below)``). ``state(t_s)`` says where it is:
``"running"`` (its motion is under way), ``"holding"`` (finished, still contributing its final pose: the
command is done) or ``"ended"`` (finished and contributing nothing: the track becomes empty).

Everything is a function of service time except the live follower (whose data arrives when it arrives).
Sources are built and validated in the submitting thread and only touched by the loop thread afterwards.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Literal, Protocol

from servoface.controller.alive.gaze import GazeConfig
from servoface.controller.alive.gaze_layer import GazeLayer
from servoface.controller.frame import AUFrame
from servoface.controller.timeline.clip import ChannelClip, Clip, Key
from servoface.controller.timeline.easing import min_jerk
from servoface.sim.rig import FaceType

State = Literal["running", "holding", "ended"]
Then = Literal["hold", "release"]


class Source(Protocol):
    name: str
    uses_below: bool

    def begin(self, t0_s: float, from_pose: Mapping[str, float]) -> None: ...

    def sample(self, t_s: float, below: Mapping[str, float]) -> Mapping[str, float]: ...

    def state(self, t_s: float) -> State: ...


class Samples(Protocol):
    """A Script, Timeline, Recording or live StreamSource: an AU frame for a (local) time."""

    def sample(self, t_s: float) -> AUFrame: ...


class ClipSource:
    """A timeline clip (ChannelClip, SequenceClip, envelope, expression) from the track's pose."""

    uses_below = False

    def __init__(self, clip: Clip, name: str | None = None, then: Then | None = None) -> None:
        """``then`` "hold" / "release" overrides the clip's own ``holds`` (None: keep it)."""
        self.clip = clip
        self.name = name or clip.name
        self.holds = clip.holds if then is None else then == "hold"
        self._t0 = 0.0
        self._from: dict[str, float] = {}
        self._end: dict[str, float] | None = None

    def begin(self, t0_s: float, from_pose: Mapping[str, float]) -> None:
        self._t0, self._from = t0_s, dict(from_pose)

    def sample(self, t_s: float, below: Mapping[str, float]) -> Mapping[str, float]:
        local = t_s - self._t0
        if local < self.clip.duration_s:
            return self.clip.sample(max(0.0, local), self._from)
        if not self.holds:
            return {}
        if self._end is None:
            self._end = self.clip.end_pose(self._from)
        return self._end

    def target_pose(self) -> dict[str, float]:
        """The pose the clip ends on (from where it started)."""
        return self.clip.end_pose(self._from) if self.holds else {}

    def state(self, t_s: float) -> State:
        if t_s - self._t0 < self.clip.duration_s - 1e-9:
            return "running"
        return "holding" if self.holds else "ended"


def transition_clip(
    pose: Mapping[str, float], transition_s: float, hold_s: float, *, merge: bool = False, name: str = "set_aus"
) -> ChannelClip:
    """Move the named AUs to ``pose`` over ``transition_s`` (minimum jerk), hold ``hold_s``. AUs the track
    had that ``pose`` does not name go to 0 over the transition (``merge`` False) or stay (``merge`` True).
    An empty pose without merge is a release: the clip ends and the track empties."""
    duration = transition_s + hold_s
    channels = {au: (Key(0.0, None), Key(transition_s, v, min_jerk), Key(duration, v)) for au, v in pose.items()}
    return ChannelClip(
        channels,
        duration,
        unlisted="hold" if merge else "to_zero",
        release_s=transition_s,
        release_easing=min_jerk,
        name=name,
        holds=bool(pose) or merge,
    )


class SamplesSource:
    """A Script / Timeline / Recording from its own time 0 at the start, for ``duration_s``; then hold
    its last frame (``then="hold"``) or end (``"release"``: the track empties)."""

    uses_below = False

    def __init__(self, samples: Samples, duration_s: float, name: str, then: Then = "hold") -> None:
        self.samples, self.duration_s, self.name, self.then = samples, duration_s, name, then
        self._t0 = 0.0
        self._last: dict[str, float] | None = None

    def begin(self, t0_s: float, from_pose: Mapping[str, float]) -> None:
        self._t0 = t0_s

    def sample(self, t_s: float, below: Mapping[str, float]) -> Mapping[str, float]:
        local = t_s - self._t0
        if local <= self.duration_s:
            return dict(self.samples.sample(max(0.0, local)).aus)
        if self.then == "release":
            return {}
        if self._last is None:
            self._last = dict(self.samples.sample(self.duration_s).aus)
        return self._last

    def state(self, t_s: float) -> State:
        if t_s - self._t0 < self.duration_s - 1e-9:
            return "running"
        return "holding" if self.then == "hold" else "ended"


class FollowSource:
    """A live source (``StreamSource``) sampled every frame, for ``duration_s`` (None: until stopped) or
    until ``until()`` is true; then hold the last AUs or release."""

    uses_below = False
    live = True  # produces anew every frame: a pose the head refuses is skipped, not the end of it

    def __init__(
        self,
        samples: Samples,
        duration_s: float | None,
        until: Callable[[], bool] | None,
        then: Then = "hold",
        name: str = "follow",
    ) -> None:
        self.samples, self.duration_s, self.until, self.then, self.name = samples, duration_s, until, then, name
        self._t0 = 0.0
        self._last: dict[str, float] = {}
        self._done = False

    def begin(self, t0_s: float, from_pose: Mapping[str, float]) -> None:
        self._t0 = t0_s

    def _over(self, t_s: float) -> bool:
        if not self._done:
            timed_out = self.duration_s is not None and t_s - self._t0 >= self.duration_s - 1e-9
            self._done = timed_out or (self.until is not None and bool(self.until()))
        return self._done

    def sample(self, t_s: float, below: Mapping[str, float]) -> Mapping[str, float]:
        if self._over(t_s):
            return self._last if self.then == "hold" else {}
        self._last = dict(self.samples.sample(t_s).aus)
        return self._last

    def state(self, t_s: float) -> State:
        if not self._done:
            return "running"
        return "holding" if self.then == "hold" else "ended"


class GazeSource:
    """Look-at targets with eye-head coordination (:class:`GazeLayer`), shifts at service times."""

    uses_below = False
    live = True  # produces anew every frame: a pose the head refuses is skipped, not the end of it
    name = "gaze"

    def __init__(self, face_type: FaceType, config: GazeConfig | None = None) -> None:
        self.layer = GazeLayer(face_type, config)
        self._busy_until_s = -math.inf

    def begin(self, t0_s: float, from_pose: Mapping[str, float]) -> None:
        pass

    def look_at(self, at_s: float, target_mm: tuple[float, float, float] | None) -> None:
        self.layer.look_at(at_s, target_mm)
        cfg = self.layer.config
        self._busy_until_s = max(self._busy_until_s, at_s + max(cfg.head_move_s, cfg.saccade_s))

    def sample(self, t_s: float, below: Mapping[str, float]) -> Mapping[str, float]:
        return self.layer.sample(t_s)

    def state(self, t_s: float) -> State:
        return "running" if t_s < self._busy_until_s else "holding"


class AliveSource:
    """An alive layer (BlinkLayer, IdleLayer) on local time since it was switched on; never ends."""

    def __init__(self, layer: object, name: str) -> None:
        self.layer = layer
        self.name = name
        self.uses_below = bool(getattr(layer, "uses_below", True))
        self.live = True  # produces anew every frame (see FollowSource.live)
        self._t0 = 0.0

    def begin(self, t0_s: float, from_pose: Mapping[str, float]) -> None:
        self._t0 = t0_s

    def sample(self, t_s: float, below: Mapping[str, float]) -> Mapping[str, float]:
        return self.layer.sample(t_s - self._t0, below)  # type: ignore[attr-defined, no-any-return]

    def state(self, t_s: float) -> State:
        return "holding"
