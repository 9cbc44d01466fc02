"""The service's named tracks and how their AUs are mixed into one frame.

A track holds at most one source at a time (a newer command on the same track takes over from where the
track is). Every frame the tracks are sampled in **layer order** and mixed per AU with the rules of
:mod:`servoface.controller.timeline.blend` (``max`` by default, clamped ``sum`` on head / eye / jaw AUs,
``override`` where a policy says so), ranked by the track **priority** (highest first) for ties and
``override``. On top of the per-AU rules a track may be declared ``mode="override"``: every AU it provides
then belongs to it outright against all lower-priority tracks (the studio's sliders, speech on the mouth),
while the AUs it does not provide blend as usual. An override of ``AU12`` also owns ``AU12L`` / ``AU12R``.

Layer order matters for the alive layers only: a source that reads ``below`` (the blink, which is
suppressed while the face already closes the lids) sees the mix of the tracks before it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

from servoface.controller.au_names import intensity_range
from servoface.controller.service.errors import ServiceError
from servoface.controller.timeline.blend import BlendPolicy, BlendRule
from servoface.sim.rig import FaceType

TrackMode = Literal["blend", "override"]
_NAME = re.compile(r"^[a-z][a-z0-9_]{0,31}$")
_SIDED = re.compile(r"^(AU\d+)([LR]?)$")


@dataclass(frozen=True)
class TrackSpec:
    """One named track: ``mode`` "blend" (per-AU rules) or "override" (owns the AUs it provides)."""

    name: str
    mode: TrackMode = "blend"
    doc: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ServiceError(f"track name {self.name!r}: expected lower-case letters, digits and _ (max 32)")
        if self.mode not in ("blend", "override"):
            raise ServiceError(f"track {self.name}: mode must be 'blend' or 'override', got {self.mode!r}")


#: The default tracks in layer order (what each front end drives is in the README, "The head service").
DEFAULT_TRACKS: tuple[TrackSpec, ...] = (
    TrackSpec("face", doc="scripts, expressions, clips, Face API calls, `servoface play`"),
    TrackSpec("gesture", doc="short nods and shakes on top of the face"),
    TrackSpec("head", doc="slow head posture"),
    TrackSpec("stream", doc="a live tracker (`servoface stream`, follow())"),
    TrackSpec("speech", "override", doc="visemes from speech: owns the mouth AUs it drives"),
    TrackSpec("gaze", doc="look-at targets (eyes lead, the neck follows)"),
    TrackSpec("studio", "override", doc="the studio's sliders: own the AUs they set"),
    TrackSpec("blink", doc="spontaneous blinks (alive layer)"),
    TrackSpec("idle", doc="idle motion (alive layer)"),
)

#: Highest first: ties and ``override`` go to the earlier track.
DEFAULT_PRIORITY: tuple[str, ...] = (
    "studio", "speech", "blink", "gaze", "stream", "gesture", "face", "head", "idle",
)  # fmt: skip


def _owned(au: str) -> tuple[str, ...]:
    """The names an override of ``au`` takes from lower tracks (a bilateral AU owns both sides)."""
    m = _SIDED.match(au)
    if m is None or m.group(2):
        return (au,)
    return (au, f"{au}L", f"{au}R")


class Mixer:
    """Mixes ``[(track, aus), ...]`` (layer order) into one pose for a face."""

    def __init__(
        self,
        face_type: FaceType,
        tracks: Sequence[TrackSpec] = DEFAULT_TRACKS,
        priority: Sequence[str] | None = None,
        rules: Mapping[str, BlendRule | str] | None = None,
    ) -> None:
        names = [t.name for t in tracks]
        if len(set(names)) != len(names):
            raise ServiceError(f"tracks: a name appears twice in {names}")
        order = tuple(priority) if priority is not None else tuple(n for n in DEFAULT_PRIORITY if n in names)
        unknown = sorted(set(order) - set(names))
        if unknown:
            raise ServiceError(f"priority: {unknown} are not tracks; have {names}")
        order += tuple(n for n in names if n not in order)  # unlisted tracks rank last, in layer order
        self.tracks: tuple[TrackSpec, ...] = tuple(tracks)
        self.priority = order
        self.policy = BlendPolicy.for_face(face_type, rules=rules, priority=order)
        self._override = frozenset(t.name for t in tracks if t.mode == "override")
        self._rank = {n: i for i, n in enumerate(order)}
        self.lo, self.hi = intensity_range(face_type)

    def mix(self, contributions: Sequence[tuple[str, Mapping[str, float]]]) -> dict[str, float]:
        """The blended pose (zeros dropped). Override tracks take their AUs from every lower track."""
        if not contributions:
            return {}
        items = list(contributions)
        if self._override and any(name in self._override for name, _ in items):
            ranked = sorted(range(len(items)), key=lambda i: self._rank.get(items[i][0], len(self._rank)))
            owned: set[str] = set()
            for i in ranked:
                name, aus = items[i]
                if owned:
                    aus = {au: v for au, v in aus.items() if au not in owned}
                    items[i] = (name, aus)
                if name in self._override:
                    for au in aus:
                        owned.update(_owned(au))
        out = self.policy.blend(items, self.lo, self.hi)
        return {au: v for au, v in out.items() if abs(v) > 1e-12}
