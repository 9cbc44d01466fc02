"""Whether a head can show everything a timeline (a script's) plays, found before it plays.

Every AU target of every clip on the timeline's tracks (its own expressions, library ones, sequences, recipes,
``from`` poses and each track's initial pose) is solved on the head, each AU at its lowest and highest value.
What the head's AU table, direct table or muscles refuse (an AU it does not know, an intensity out of its
range) is a ScriptError naming where the timeline came from, the expression and its track. The alive layers
(blink, gaze, idle) are not expressions a script names and are not solved here. `servoface play` runs it
before the head opens; `HeadService.play` before a command is placed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from servoface.controller.errors import ControllerError, ScriptError
from servoface.sim.errors import SimError

Solve = Callable[[Mapping[str, float]], object]  # raises SimError / ControllerError for a pose the head refuses


def pose_refusal(solve: Solve, aus: Mapping[str, float], what: str, head_name: str) -> str | None:
    """None when ``solve`` (the head's AU -> targets solver) takes the pose ``aus``; else why not, in the one
    wording every check of a pose on a head uses: ``"{what}, on head 'name': {reason}"``. The caller raises
    its own error type with it (an expression before a command opens the head, `Face.express`, a service
    command, each AU extreme of a script)."""
    try:
        solve(aus)
    except (SimError, ControllerError) as err:
        return f"{what}, on head {head_name!r}: {err}"
    return None


def check_timeline_on_head(timeline: Any, solve: Solve, source: str, head_name: str) -> None:
    """ScriptError for the first AU extreme of ``timeline`` that ``solve`` refuses (see the module doc)."""
    from servoface.controller.timeline.track import Track

    extremes: dict[tuple[str, bool], tuple[float, str]] = {}  # (AU, high?) -> (value, where it is asked for)
    for track_name in timeline.layer_names:
        track = timeline.layer(track_name)
        if not isinstance(track, Track):
            continue  # an alive layer
        _note(extremes, track.initial_pose.items(), f"script.initial (track {track_name})")
        for placed in track.items:
            for clip in leaf_clips(placed.clip):  # a sequence's own expressions, each by its name
                _note(extremes, clip.targets(), f"expression {clip.name!r} (track {track_name})")
            _note(
                extremes,
                (placed.from_pose or {}).items(),
                f"the from pose of {placed.clip.name!r} (track {track_name})",
            )
    _solve_all(extremes, solve, source, head_name)


def check_clip_on_head(clip: Any, solve: Solve, head_name: str) -> None:
    """`check_timeline_on_head` for one clip (a sequence: each of its clips)."""
    extremes: dict[tuple[str, bool], tuple[float, str]] = {}
    for leaf in leaf_clips(clip):
        _note(extremes, leaf.targets(), f"expression {leaf.name!r}")
    _solve_all(extremes, solve, f"clip {getattr(clip, 'name', '?')!r}", head_name)


def leaf_clips(clip: Any) -> list[Any]:
    """``clip``, or the clips a sequence plays one after another (recursively)."""
    parts = getattr(clip, "clips", None)
    return [leaf for part in parts for leaf in leaf_clips(part)] if parts else [clip]


def _note(extremes: dict[tuple[str, bool], tuple[float, str]], pairs: Iterable[tuple[str, float]], what: str) -> None:
    for au, value in pairs:
        for high in (False, True):
            known = extremes.get((au, high))
            if known is None or (value > known[0] if high else value < known[0]):
                extremes[au, high] = (value, what)


def _solve_all(extremes: Mapping[tuple[str, bool], tuple[float, str]], solve: Solve, source: str, head: str) -> None:
    for (au, _), (value, what) in extremes.items():
        why = pose_refusal(solve, {au: value}, what, head)
        if why is not None:
            raise ScriptError(f"{source}: {why}")
