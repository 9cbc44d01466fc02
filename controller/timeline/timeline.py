"""The timeline: named layers (tracks and alive behaviours) blended into one AU frame per time.

``Timeline.sample(t_s) -> AUFrame`` is a pure function of ``t_s``: the pipeline calls it every control
frame with the frame's scheduled time, so a late frame is simply skipped and keyframes land on time.

Layers are evaluated in the order they were added; each gets ``below``, the blend of the layers before it
(the blink behaviour uses that to see whether the face already closes the lids). The default layer order
is face, gesture, speech, head, gaze, then whatever alive layers the caller adds (blink, idle).
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable, Iterator, Mapping
from typing import Protocol

from servoface.controller.au_names import intensity_range
from servoface.controller.errors import FrameError, TimelineError
from servoface.controller.frame import AUFrame, FrameValidator, check_face_type
from servoface.controller.timeline.blend import BlendPolicy
from servoface.controller.timeline.clip import Clip, Pose
from servoface.controller.timeline.track import Placed, Track
from servoface.sim.rig import FaceType

STANDARD_TRACKS: tuple[str, ...] = ("face", "gesture", "speech", "head", "gaze")


class Layer(Protocol):
    """Anything that yields AUs for a time, given the blend of the layers below it.

    A layer that ignores ``below`` may say so with a class attribute ``uses_below = False``; the timeline
    then skips blending before calling it (an optimisation only; it is handed a stale mapping). One that
    reads only some AUs of it may name them in ``below_aus`` (a frozenset): it is then handed those of the
    blend (`BlendPolicy.blend(only=)`), and must read no others.
    """

    def sample(self, t_s: float, below: Pose) -> Mapping[str, float]: ...


class Timeline:
    """Tracks of clips plus alive layers for one face type, blended by a :class:`BlendPolicy`."""

    def __init__(
        self,
        face_type: FaceType,
        *,
        allowed: frozenset[str] | None = None,
        blend: BlendPolicy | None = None,
        initial_pose: Pose | None = None,
    ) -> None:
        self.face_type: FaceType = check_face_type(face_type)
        self.validator = FrameValidator(face_type, allowed)
        self.blend = blend or BlendPolicy.for_face(face_type)
        self._initial = self.validator.pose(initial_pose or {}, where="initial_pose")
        self._layers: dict[str, Layer] = {}
        # when any track plays, merged (`is_playing`), for the layer count and `Track.changes` it was built at
        self._playing: tuple[tuple[int, int], list[float], list[float]] = ((-1, -1), [], [])
        self._range = intensity_range(face_type)

    # -- building ---------------------------------------------------------------------------------
    def track(self, name: str) -> Track:
        """The track called ``name``, created (empty) on first use. The "face" track starts from
        ``initial_pose``."""
        layer = self._layers.get(name)
        if layer is None:
            track = Track(name, self._initial if name == "face" else None)
            self._layers[name] = track
            return track
        if not isinstance(layer, Track):
            raise TimelineError(f"layer {name!r} is a {type(layer).__name__}, not a track of clips")
        return layer

    def add_layer(self, name: str, layer: Layer) -> None:
        """Add an alive behaviour (blink, gaze, idle) or any custom layer under ``name``."""
        if name in self._layers:
            raise TimelineError(f"layer {name!r} already exists; choose another name")
        self._layers[name] = layer

    def layer(self, name: str) -> Layer:
        try:
            return self._layers[name]
        except KeyError:
            raise TimelineError(f"no layer {name!r}; have {', '.join(self._layers) or 'none'}") from None

    @property
    def layer_names(self) -> tuple[str, ...]:
        return tuple(self._layers)

    def play(self, clip: Clip, at_s: float = 0.0, *, track: str = "face", from_pose: Pose | None = None) -> Placed:
        """Place ``clip`` on ``track`` at ``at_s``; it starts from that track's pose then (or ``from_pose``).

        The clip's AUs and values are checked against this face now, not mid-performance.
        """
        for au, value in clip.targets():
            try:
                self.validator.pose({au: value}, where=f"{clip.name}")
            except FrameError as err:
                raise TimelineError(f"track {track}: {err}") from err
        start = None if from_pose is None else self.validator.pose(from_pose, where="from_pose")
        return self.track(track).add(at_s, clip, start)

    # -- playing ----------------------------------------------------------------------------------
    def sample_aus(self, t_s: float) -> dict[str, float]:
        """Blended AU intensities at ``t_s`` (no validation; zeros dropped)."""
        contributions: list[tuple[str, Mapping[str, float]]] = []
        below: dict[str, float] = {}
        fresh = True
        lo, hi = self._range
        for name, layer in self._layers.items():
            if not fresh and getattr(layer, "uses_below", True):
                only = getattr(layer, "below_aus", None)  # a layer that reads just these AUs of `below`
                below, fresh = self.blend.blend(contributions, lo, hi, only), only is None
            aus = layer.sample(t_s, below)
            if aus:
                contributions.append((name, aus))
                fresh = False
        if not fresh:
            below = self.blend.blend(contributions, lo, hi)
        return {au: v for au, v in below.items() if abs(v) > 1e-12}

    def sample(self, t_s: float) -> AUFrame:
        """The validated frame at ``t_s`` (FrameError if a layer produced something this face rejects)."""
        return self.validator(t_s, self.sample_aus(t_s))

    def frames(self, rate_hz: float, start_s: float = 0.0, end_s: float | None = None) -> Iterator[AUFrame]:
        """Frames at ``rate_hz`` from ``start_s`` to ``end_s`` (default: the end of the last clip), for
        offline rendering. Frame k is at exactly ``start_s + k / rate_hz``."""
        if not rate_hz > 0:
            raise TimelineError(f"rate_hz: expected > 0, got {rate_hz!r}")
        stop = self.end_s if end_s is None else end_s
        k = 0
        while start_s + k / rate_hz <= stop + 1e-9:
            yield self.sample(start_s + k / rate_hz)
            k += 1

    @property
    def end_s(self) -> float:
        """End of the last clip on any track (alive layers run forever and do not count)."""
        return max((layer.end_s for layer in self._layers.values() if isinstance(layer, Track)), default=0.0)

    def is_playing(self, t_s: float) -> bool:
        """True while any track has a clip running at ``t_s`` (`is_playing_plain`, from the union of the
        tracks' playing spans, rebuilt when a track changes)."""
        key = (len(self._layers), Track.changes)  # layers are only ever added; any track's change counts
        if key != self._playing[0]:
            tracks = [x for x in self._layers.values() if isinstance(x, Track)]
            self._playing = (key, *_union(span for track in tracks for span in track.playing_spans()))
        _, starts, stops = self._playing
        j = bisect.bisect_right(starts, t_s) - 1
        return j >= 0 and t_s < stops[j]

    def is_playing_plain(self, t_s: float) -> bool:
        """`is_playing` track by track (the straightforward form; tests compare the two)."""
        return any(layer.is_playing(t_s) for layer in self._layers.values() if isinstance(layer, Track))


def _union(spans: Iterable[tuple[float, float]]) -> tuple[list[float], list[float]]:
    """Half-open spans merged into disjoint ones in time order: (starts, stops)."""
    starts: list[float] = []
    stops: list[float] = []
    for start, stop in sorted(spans):
        if stops and start <= stops[-1]:
            stops[-1] = max(stops[-1], stop)
        else:
            starts.append(start)
            stops.append(stop)
    return starts, stops
