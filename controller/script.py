"""Timeline scripts in TOML: poses, expressions and when to play them, gaze, blinks, idle, blend rules.

A script becomes a :class:`~servoface.controller.timeline.Timeline`; ``Script.sample(t_s) -> AUFrame``. Every error
is a :class:`ScriptError` naming the file, the key path (and the line when it can be found); TOML syntax
errors carry tomllib's line and column. The format (all times in seconds, intensities per face):

    [script]                 face = "human" | "dog" (required); title; end_s; initial = pose name/table;
                             audio = "speech.wav" + audio_start_s (the sound that goes with it, beside the file)
    [poses]                  name = { AU12 = 0.8, ... }        (complete: AUs not named are 0)
    [expressions.<name>]     one of:
        duration_s + movements = [{ pose = "name" | {..}, percent = 30 | share = 0.3, easing = ".." }]
        pose + onset_s + apex_s + offset_s [+ easing]          (onset / apex / offset envelope)
        keyframes = [{ t_s = 0.2, pose = .., easing = ".." }]  (poses reached at clip times)
        channels = { AU26 = [[t_s, value], ...], ... } [+ holds = false]  (per-AU keys, linear;
                                 what `servoface say` / `lipsync` write for the speech track)
        events = ["AU14", "-AU9", 7, {au = "AU7", value = 0.5}] | recipe = "anger"  [+ timing, repeat] (dog)
        library = "happiness" [+ onset_s, apex_s, offset_s, easing | + timing (dog)]  (servoface.sim.expressions)
    [[play]]                 at_s, track = "face" (default) | any name; expression = "name" |
                             sequence = ["a", "b"] | recipe = "anger" | library = "happiness" |
                             say = "words" [+ voice = "en-us"] (lip sync, always on track "speech";
                             script_say.py); from = pose (optional start pose)
    [[gaze]]                 at_s, look_at_mm = [x, y, z] (head frame: +x head's left, +y up, +z forward)
                             | ahead = true
    [gaze_setup]             eye_center_mm, neck_pivot_mm, eye_range_yaw_deg, eye_range_pitch_deg,
                             saccade_s, head_move_s (GazeConfig; AU full scales come from the AU table)
    [blink]                  seed, mean_interval_s, ... (BlinkConfig); enabled = false to switch off
    [idle]                   seed, head_amplitude, ... (IdleConfig); enabled = false to switch off
    [blend]                  default = "max"; priority = [tracks...]; rules = { AU26 = "sum", ... }
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from servoface.controller.alive import BlinkConfig, BlinkLayer, GazeLayer, IdleConfig, IdleLayer
from servoface.controller.alive.gaze import gaze_config_for
from servoface.controller.errors import FrameError, ScriptError, TimelineError
from servoface.controller.frame import AUFrame, FrameValidator
from servoface.controller.script_fields import Reader, shown
from servoface.controller.script_say import SAY_TRACK, check_say, say_clip, say_problem, with_say_rules
from servoface.controller.timeline import (
    BlendPolicy,
    ChannelClip,
    Clip,
    Event,
    EventTiming,
    Expression,
    Key,
    Movement,
    Timeline,
    easing_by_name,
    events_clip,
    parse_events,
    recipe_events,
    sequence,
)
from servoface.controller.timeline.library import library_clip, load_expressions
from servoface.sim.rig import FaceType

SCRIPTS_DIR = Path(__file__).resolve().parent / "scripts"
ALIVE_LAYERS = ("gaze", "blink", "idle")
_TOP = ("script", "poses", "expressions", "play", "gaze", "gaze_setup", "blink", "idle", "blend")
_TRACK_RE = re.compile(r"^[a-z][a-z0-9_]*$")


MAX_SCRIPT_S = 24 * 3600.0  # a script is at most a day long (loop it from code for longer)
MAX_REPEAT = 10_000
MAX_EVENTS = 1000
ALIVE_MINIMUMS = {  # seconds: blinks and idle motion no faster than a head can follow
    "blink": {"mean_interval_s": 0.5, "min_duration_s": 0.05, "max_duration_s": 0.05},
    "idle": {"head_period_s": 0.2, "eye_period_s": 0.2},
}


@dataclass
class Script:
    """A loaded script: its timeline plus what it was built from."""

    source: str
    title: str
    face_type: FaceType
    timeline: Timeline
    end_s: float
    poses: dict[str, dict[str, float]] = field(default_factory=dict)
    clips: dict[str, Clip] = field(default_factory=dict)
    audio: str = ""  # a sound file beside the script (speech), started at audio_start_s
    audio_start_s: float = 0.0

    @property
    def audio_path(self) -> Path | None:
        return Path(self.source).parent / self.audio if self.audio else None

    def sample(self, t_s: float) -> AUFrame:
        return self.timeline.sample(t_s)


def example_scripts() -> list[Path]:
    """The example scripts shipped in ``controller/scripts/``."""
    return sorted(SCRIPTS_DIR.glob("*.toml"))


def load_script(
    path: str | Path, *, allowed: frozenset[str] | None = None, library: str | Path | None = None
) -> Script:
    """Read and build a script file, or a shipped script by name (``human_performance``, see
    :mod:`servoface.controller.shipped`). ``allowed`` = the head's AU names (default: the face's built-in set);
    ``library`` = the head's own expression library file (its profile's ``expressions``), which the script's
    ``library = "name"`` entries then name expressions of (default: the face type's built-in library)."""
    from servoface.controller.shipped import resolve_script
    from servoface.sim.textfile import read_utf8

    p = resolve_script(path)
    try:
        text = read_utf8(p, ScriptError, what="a script file")
    except OSError as err:
        hint = ""
        if isinstance(path, str) and "/" not in path and not p.exists():  # a name: perhaps a shipped one misspelt
            from servoface.controller.shipped import shipped_scripts

            names = sorted(shipped_scripts())
            close = difflib.get_close_matches(path.removesuffix(".toml"), names, n=1)
            hint = (f" (did you mean {close[0]!r}?)" if close else "") + f"; shipped scripts: {names}"
        raise ScriptError(f"{p}: cannot read script ({err.strerror or err}){hint}") from err
    return parse_script(text, source=str(p), allowed=allowed, library=library)


def parse_script(
    text: str,
    *,
    source: str = "<script>",
    allowed: frozenset[str] | None = None,
    library: str | Path | None = None,
) -> Script:
    """Build a script from TOML text; ``source`` names it in errors."""
    r = Reader(source, text)
    try:
        data = tomllib.loads(text)
    except RecursionError as err:
        raise ScriptError(f"{source}: nested too deeply to be a script") from err
    except tomllib.TOMLDecodeError as err:
        match = re.search(r"line (\d+)", str(err))
        line = int(match.group(1)) if match else None
        exc = ScriptError(
            f"{source}:{line}: TOML syntax error: {err}" if line else f"{source}: TOML syntax error: {err}"
        )
        exc.file, exc.key_path, exc.line = source, "", line  # type: ignore[attr-defined]
        raise exc from err
    return _Builder(r, allowed, library).build(data)


class _Builder:
    def __init__(self, reader: Reader, allowed: frozenset[str] | None, library: str | Path | None = None) -> None:
        self.r = reader
        self.allowed = allowed
        self.library_file = library  # the head's own expression library (None: the face type's built-in one)

    def build(self, data: Mapping[str, Any]) -> Script:
        r = self.r
        data = r.table(data, "")
        r.keys(data, "", _TOP)
        head = r.table(r.get(data, "script", "", required=True), "script")
        r.keys(head, "script", ("face", "title", "end_s", "initial", "audio", "audio_start_s"))
        face = r.string(head, "face", "script")
        if face not in ("human", "dog"):
            r.fail("script.face", f"expected 'human' or 'dog', got {shown(face)}")
        self.face: FaceType = face  # type: ignore[assignment]
        self.validator = FrameValidator(self.face, self.allowed)
        self.poses = {
            name: self.pose(value, f"poses.{name}", by_name=False)
            for name, value in r.table(r.get(data, "poses", "", {}), "poses").items()
        }
        initial = self.pose(head["initial"], "script.initial") if "initial" in head else {}
        blend_table = r.table(r.get(data, "blend", "", {}), "blend")
        blend = self.blend(with_say_rules(blend_table, data.get("play"), self.face))
        self.timeline = Timeline(self.face, allowed=self.allowed, blend=blend, initial_pose=initial)
        self.timeline.track("face")
        self.clips: dict[str, Clip] = {}
        for name, spec in r.table(r.get(data, "expressions", "", {}), "expressions").items():
            self.clips[name] = self.expression(name, r.table(spec, f"expressions.{name}"))
        for i, entry in enumerate(r.array(data, "play", "", [])):
            self.play(r.table(entry, f"play[{i}]"), f"play[{i}]")
        self.gaze(r.array(data, "gaze", "", []), r.table(r.get(data, "gaze_setup", "", {}), "gaze_setup"))
        self.alive(data)
        end = max(self.timeline.end_s, self.gaze_end_s)
        end_s = r.number(head, "end_s", "script", None, lo=0.0, hi=MAX_SCRIPT_S, what="an end time in seconds")
        if end_s is None and end > MAX_SCRIPT_S:  # every time is within a day, but not every start + its length
            r.fail(
                "script.end_s",
                f"the play and gaze entries run to {end:g} s; expected a script of at most {MAX_SCRIPT_S:g} s "
                "(start them earlier, shorten them, or set end_s to cut the script there)",
            )
        title = r.string(head, "title", "script", Path(r.source).stem)
        audio = r.string(head, "audio", "script", "")
        if audio and (Path(audio).is_absolute() or ".." in Path(audio).parts):
            r.fail("script.audio", f"expected a file name beside the script (no absolute path, no '..'), got {audio!r}")
        audio_start = r.number(head, "audio_start_s", "script", 0.0, lo=0.0, hi=3600.0, what="seconds >= 0")
        return Script(
            r.source,
            title,
            self.face,
            self.timeline,
            end if end_s is None else end_s,
            self.poses,
            self.clips,
            audio=audio,
            audio_start_s=audio_start,
        )

    # -- pieces -----------------------------------------------------------------------------------
    def pose(self, value: Any, path: str, *, by_name: bool = True) -> dict[str, float]:
        if isinstance(value, str) and by_name:
            if value not in self.poses:
                known = ", ".join(sorted(self.poses)) or "none defined"
                self.r.fail(path, f"unknown pose {shown(value)}; expected a pose name ({known}) or an inline table")
            return self.poses[value]
        table = self.r.table(value, path)
        try:
            return self.validator.pose(table, where=path)
        except FrameError as err:
            self.r.fail(_first_path(str(err), path), _strip_path(str(err)), err)

    def easing(self, table: Mapping[str, Any], path: str, default: str = "linear") -> Any:
        name = self.r.string(table, "easing", path, default)
        try:
            return easing_by_name(name, field=f"{path}.easing")
        except TimelineError as err:
            self.r.fail(f"{path}.easing", _strip_path(str(err)), err)

    def expression(self, name: str, spec: Mapping[str, Any], path: str | None = None) -> Clip:
        r, path = self.r, path or f"expressions.{name}"
        try:
            if "library" in spec:
                return self.library(name, spec, path)
            if "movements" in spec:
                r.keys(spec, path, ("duration_s", "movements"))
                duration = r.number(
                    spec, "duration_s", path, lo=1e-6, hi=MAX_SCRIPT_S, what="a duration in seconds > 0"
                )
                moves = []
                for i, m in enumerate(r.array(spec, "movements", path)):
                    mpath = f"{path}.movements[{i}]"
                    m = r.table(m, mpath)
                    r.keys(m, mpath, ("pose", "share", "percent", "easing"))
                    if ("share" in m) == ("percent" in m):
                        r.fail(mpath, "expected exactly one of share (0..1) or percent (0..100)")
                    share = (
                        r.number(m, "share", mpath, lo=0, hi=1, what="a share 0..1")
                        if "share" in m
                        else r.number(m, "percent", mpath, lo=0, hi=100, what="a percentage 0..100") / 100
                    )
                    pose = self.pose(r.get(m, "pose", mpath, required=True), f"{mpath}.pose")
                    moves.append(Movement(pose, share, self.easing(m, mpath)))
                return Expression(name, duration, tuple(moves)).clip()
            if "channels" in spec:
                return self.channels(name, spec, path)
            if "keyframes" in spec:
                r.keys(spec, path, ("keyframes",))
                return self.keyframes(name, r.array(spec, "keyframes", path), path)
            if "onset_s" in spec or "apex_s" in spec or "offset_s" in spec:
                r.keys(spec, path, ("pose", "onset_s", "apex_s", "offset_s", "easing"))
                pose = self.pose(r.get(spec, "pose", path, required=True), f"{path}.pose")
                what = "a duration in seconds >= 0"
                onset, apex, offset = (
                    r.number(spec, k, path, lo=0, hi=MAX_SCRIPT_S, what=what) for k in ("onset_s", "apex_s", "offset_s")
                )
                if onset + apex + offset <= 0:
                    r.fail(path, "onset_s + apex_s + offset_s must be > 0")
                ease = self.easing(spec, path, "min_jerk")
                return Expression.envelope(name, pose, onset, apex, offset, easing=ease).clip()
            if "events" in spec or "recipe" in spec:
                return self.events(name, spec, path)
        except (TimelineError, FrameError) as err:
            r.fail(_first_path(str(err), path), _strip_path(str(err)), err)
        r.fail(
            path,
            "expected movements (+ duration_s), keyframes, onset_s/apex_s/offset_s (+ pose), or events/recipe",
        )

    def keyframes(self, name: str, keys: list[Any], path: str) -> Clip:
        r = self.r
        if not keys:
            r.fail(f"{path}.keyframes", "expected at least one keyframe")
        times, moves, prev = [], [], 0.0
        for i, k in enumerate(keys):
            kpath = f"{path}.keyframes[{i}]"
            k = r.table(k, kpath)
            r.keys(k, kpath, ("t_s", "pose", "easing"))
            t = r.number(k, "t_s", kpath, lo=0, hi=MAX_SCRIPT_S, what="a clip time in seconds >= 0")
            if t < prev:
                r.fail(f"{kpath}.t_s", f"keyframes must be in time order; {t:g} s comes after {prev:g} s")
            times.append(t)
            moves.append((self.pose(r.get(k, "pose", kpath, required=True), f"{kpath}.pose"), self.easing(k, kpath)))
            prev = t
        duration = times[-1]
        if duration <= 0:
            r.fail(f"{path}.keyframes", "the last keyframe must be at t_s > 0")
        shares = [(b - a) / duration for a, b in zip([0.0, *times[:-1]], times, strict=True)]
        movements = tuple(Movement(p, s, e) for (p, e), s in zip(moves, shares, strict=True))
        return Expression(name, duration, movements).clip()

    def channels(self, name: str, spec: Mapping[str, Any], path: str) -> Clip:
        """Per-AU keys ``[[t_s, value], ...]`` (linear between keys); AUs not named keep their value."""
        r = self.r
        r.keys(spec, path, ("channels", "holds"))
        table = r.table(r.get(spec, "channels", path, required=True), f"{path}.channels")
        if not table:
            r.fail(f"{path}.channels", "expected at least one AU channel")
        channels: dict[str, tuple[Key, ...]] = {}
        end = 0.0
        for au, keys in table.items():
            cpath = f"{path}.channels.{au}"
            keys = r.array(table, au, f"{path}.channels")
            if not keys or len(keys) > 100_000:
                r.fail(cpath, "expected 1..100000 keys [t_s, value]")
            out, prev = [], 0.0
            for i, key in enumerate(keys):
                kpath = f"{cpath}[{i}]"
                if not isinstance(key, list) or len(key) != 2:
                    r.fail(kpath, f"expected [t_s, value], got {key!r:.60}")
                t, v = key
                if isinstance(t, bool) or not isinstance(t, int | float) or not (prev <= t < 3600.0):
                    r.fail(kpath, f"expected a time in seconds, in order (>= {prev:g}, < 3600), got {t!r:.40}")
                pose = self.pose({au: v}, kpath, by_name=False)
                ((canonical, value),) = pose.items()
                out.append(Key(float(t), value))
                prev = float(t)
            channels[canonical] = tuple(out)
            end = max(end, prev)
        if end <= 0:
            r.fail(f"{path}.channels", "the last key must be at t_s > 0")
        holds = spec.get("holds", True)
        if not isinstance(holds, bool):
            r.fail(f"{path}.holds", f"expected true or false, got {holds!r:.40}")
        return ChannelClip(channels, end, unlisted="hold", name=name, holds=holds)

    def library(self, name: str, spec: Mapping[str, Any], path: str) -> Clip:
        r = self.r
        if self.face == "dog":
            r.keys(spec, path, ("library", "timing"))
            timing = None
            if "timing" in spec:
                timing = self.timing(r.table(spec["timing"], f"{path}.timing"), f"{path}.timing")
            return library_clip("dog", r.string(spec, "library", path), timing=timing, source=self.library_file)
        r.keys(spec, path, ("library", "onset_s", "apex_s", "offset_s", "easing"))
        what = "a duration in seconds >= 0"
        times = {
            k: r.number(spec, k, path, None, lo=0, hi=MAX_SCRIPT_S, what=what)
            for k in ("onset_s", "apex_s", "offset_s")
        }
        given = {k: v for k, v in times.items() if v is not None}
        return library_clip(
            "human",
            r.string(spec, "library", path),
            easing=self.easing(spec, path, "min_jerk"),
            source=self.library_file,
            **given,
        )

    def events(self, name: str, spec: Mapping[str, Any], path: str) -> Clip:
        r = self.r
        r.keys(spec, path, ("events", "recipe", "timing", "repeat"))
        if ("events" in spec) == ("recipe" in spec):
            r.fail(path, "expected exactly one of events = [...] or recipe = '<name>'")
        if self.face != "dog":
            r.fail(path, "DFACS events and recipes are for the dog face; use movements for the human face")
        if "recipe" in spec:
            events: tuple[Event, ...] = recipe_events(r.string(spec, "recipe", path))
        else:
            events = parse_events(r.array(spec, "events", path), field=f"{path}.events")
        timing = self.timing(r.table(r.get(spec, "timing", path, {}), f"{path}.timing"), f"{path}.timing")
        repeat = r.integer(spec, "repeat", path, 1, lo=1, hi=MAX_REPEAT)
        clip = events_clip(events[:MAX_EVENTS], timing, repeat=1, name=name)
        if len(events) > MAX_EVENTS or clip.duration_s * repeat > MAX_SCRIPT_S:
            r.fail(
                f"{path}.repeat",
                f"{len(events)} events x {repeat} repeats ({clip.duration_s * repeat:g} s) is more than a script may "
                f"hold ({MAX_EVENTS} events, {MAX_SCRIPT_S:g} s)",
            )
        clip = events_clip(events, timing, repeat=repeat, name=name)
        for au, value in clip.targets():
            self.pose({au: value}, f"{path}.events")
        return clip

    def timing(self, table: Mapping[str, Any], path: str) -> EventTiming:
        names = [f.name for f in fields(EventTiming) if f.name not in ("easing", "exclusive")]
        self.r.keys(table, path, (*names, "easing"))
        changes: dict[str, Any] = {}
        for key in names:
            if key == "iterations" and key in table:
                changes[key] = self.r.integer(table, key, path, lo=1)
            elif key in table:
                seconds = key.endswith("_s")
                hi = MAX_SCRIPT_S if seconds else math.inf
                changes[key] = self.r.number(table, key, path, lo=0, hi=hi, what=f"{key} >= 0")
        if "easing" in table:
            changes["easing"] = self.easing(table, path, "min_jerk")
        return EventTiming(**changes)

    def play(self, entry: Mapping[str, Any], path: str) -> None:
        r = self.r
        r.keys(entry, path, ("at_s", "track", "expression", "sequence", "recipe", "library", "say", "voice", "from"))
        at = r.number(entry, "at_s", path, lo=0, hi=MAX_SCRIPT_S, what="a start time in seconds >= 0")
        track = r.string(entry, "track", path, "speech" if "say" in entry else "face")
        if not _TRACK_RE.match(track) or track in ALIVE_LAYERS:
            r.fail(
                f"{path}.track",
                f"expected a track name like 'face', 'gesture', 'speech' "
                f"(not {', '.join(ALIVE_LAYERS)}), got {shown(track)}",
            )
        if "say" in entry and track != SAY_TRACK:  # one mouth, one speech track: see script_say's docstring
            r.fail(
                f"{path}.track",
                f"a say cue is spoken on the head's one speech track: leave track out or write "
                f"track = '{SAY_TRACK}', got {shown(track)}",
            )
        kinds = [k for k in ("expression", "sequence", "recipe", "library", "say") if k in entry]
        if len(kinds) != 1:
            r.fail(
                path,
                "expected exactly one of expression = '<name>', sequence = [names], recipe = '<dog recipe>', "
                "library = '<library expression>', say = '<words>'",
            )
        if "voice" in entry and kinds[0] != "say":
            r.fail(f"{path}.voice", "voice goes with say = '<words>'")
        if kinds[0] == "say":
            clip = self.say(entry, path)
        elif kinds[0] == "expression":
            clip = self.clip_ref(r.string(entry, "expression", path), f"{path}.expression")
        elif kinds[0] == "sequence":
            names = r.array(entry, "sequence", path)
            if not names:
                r.fail(f"{path}.sequence", "expected at least one expression name")
            parts = [self.clip_ref(n, f"{path}.sequence[{i}]") for i, n in enumerate(names)]
            clip = sequence(parts, name="+".join(map(str, names)))  # type: ignore[arg-type]
        elif kinds[0] == "recipe":
            clip = self.events("recipe", {"recipe": entry["recipe"]}, path)
        else:
            try:
                clip = self.library(str(entry["library"]), {"library": entry["library"]}, path)
            except TimelineError as err:
                r.fail(f"{path}.library", str(err), err)
        start = self.pose(entry["from"], f"{path}.from") if "from" in entry else None
        try:
            self.timeline.play(clip, at, track=track, from_pose=start)
        except (TimelineError, FrameError) as err:
            r.fail(path, str(err), err)

    def say(self, entry: Mapping[str, Any], path: str) -> Clip:
        text, voice = entry["say"], entry.get("voice", "en-us")
        problem = check_say(text, voice)
        if problem is not None:
            r_field, _, message = problem.partition(": ")
            self.r.fail(f"{path}.{r_field}", message)
        try:
            return say_clip(text, voice, self.face, self.allowed, name=f"say: {text[:40]}")
        except Exception as err:  # noqa: BLE001 - espeak-ng missing or refusing: a script error naming the cue
            r_field, message = say_problem(err)
            self.r.fail(f"{path}.{r_field}", message, err)

    def clip_ref(self, name: Any, path: str) -> Clip:
        if not isinstance(name, str) or name not in self.clips:
            known = ", ".join(sorted(self.clips)) or "none defined"
            self.r.fail(
                path, f"unknown expression {shown(name)}; expected one of: {known}{self.library_hint(name, path)}"
            )
        return self.clips[name]

    def library_hint(self, name: Any, path: str) -> str:
        """For a name that is not the script's own but an expression of the face's library: how to play it."""
        try:
            in_library = isinstance(name, str) and (
                name in load_expressions(self.face)
                or (self.library_file is not None and name in load_expressions(self.library_file))
            )
        except TimelineError:
            return ""
        if not in_library:
            return ""
        if path.endswith(".expression"):
            how = f"write library = {name!r} instead of expression = {name!r}"
        else:
            how = f"define it first: [expressions.{name}] library = {name!r}"
        return f" ({name!r} is in the {self.face} expression library: {how})"

    def gaze(self, entries: list[Any], setup: Mapping[str, Any]) -> None:
        self.gaze_end_s = 0.0
        if not entries:
            return
        keys = (
            "eye_center_mm",
            "neck_pivot_mm",
            "eye_range_yaw_deg",
            "eye_range_pitch_deg",
            "saccade_s",
            "head_move_s",
        )
        self.r.keys(setup, "gaze_setup", keys)
        values: dict[str, Any] = {}
        for key in keys:
            if key.endswith("_mm") and key in setup:
                raw = self.r.array(setup, key, "gaze_setup")
                if len(raw) != 3 or not all(isinstance(c, int | float) and not isinstance(c, bool) for c in raw):
                    self.r.fail(f"gaze_setup.{key}", f"expected [x, y, z] in mm (head frame), got {shown(raw)}")
                values[key] = tuple(float(c) for c in raw)
            elif key in setup:
                values[key] = self.r.number(setup, key, "gaze_setup", lo=1e-6, what="a positive number")
        try:
            config = gaze_config_for(self.face, **values)
        except TimelineError as err:
            self.r.fail("gaze_setup", str(err), err)
        layer = GazeLayer(self.face, config)
        self.timeline.add_layer("gaze", layer)
        for i, entry in enumerate(entries):
            path = f"gaze[{i}]"
            entry = self.r.table(entry, path)
            self.r.keys(entry, path, ("at_s", "look_at_mm", "ahead"))
            at = self.r.number(entry, "at_s", path, lo=0, hi=MAX_SCRIPT_S, what="a time in seconds >= 0")
            if ("look_at_mm" in entry) == bool(entry.get("ahead", False)):
                self.r.fail(path, "expected exactly one of look_at_mm = [x, y, z] or ahead = true")
            target = None
            if "look_at_mm" in entry:
                raw = self.r.array(entry, "look_at_mm", path)
                if len(raw) != 3 or not all(isinstance(c, int | float) and not isinstance(c, bool) for c in raw):
                    self.r.fail(f"{path}.look_at_mm", f"expected [x, y, z] in mm (head frame), got {shown(raw)}")
                target = (float(raw[0]), float(raw[1]), float(raw[2]))
            try:
                layer.look_at(at, target)
            except TimelineError as err:
                self.r.fail(f"{path}.look_at_mm", str(err), err)
            self.gaze_end_s = max(self.gaze_end_s, at + config.head_move_s)

    def alive(self, data: Mapping[str, Any]) -> None:
        for key, config_cls in (("blink", BlinkConfig), ("idle", IdleConfig)):
            if key not in data:
                continue
            table = dict(self.r.table(data[key], key))
            names = [f.name for f in fields(config_cls)]
            self.r.keys(table, key, ("enabled", "seed", *names))
            if not table.pop("enabled", True):
                continue
            seed = self.r.integer(table, "seed", key, 0)
            table.pop("seed", None)
            values = {k: self.r.number(table, k, key) for k in table}
            for field_name, minimum in ALIVE_MINIMUMS.get(key, {}).items():
                if field_name in values and values[field_name] < minimum:
                    self.r.fail(
                        f"{key}.{field_name}",
                        f"{values[field_name]:g} s is below the {minimum:g} s a head can follow "
                        "(a faster layer only floods the loop)",
                    )
            try:
                config = config_cls(**values)
            except TimelineError as err:
                self.r.fail(key, str(err), err)
            if key == "blink":
                self.timeline.add_layer("blink", BlinkLayer(self.face, seed, config))  # type: ignore[arg-type]
            else:
                busy = self.timeline.is_playing
                self.timeline.add_layer("idle", IdleLayer(self.face, seed, config, busy=busy))  # type: ignore[arg-type]

    def blend(self, table: Mapping[str, Any]) -> BlendPolicy:
        r = self.r
        r.keys(table, "blend", ("default", "priority", "rules"))
        rules = r.table(r.get(table, "rules", "blend", {}), "blend.rules")
        priority = r.array(table, "priority", "blend", [])
        if not all(isinstance(p, str) for p in priority):
            r.fail("blend.priority", f"expected an array of track names, got {shown(priority)}")
        try:
            return BlendPolicy.for_face(self.face, rules, priority or None, r.string(table, "default", "blend", "max"))
        except (TimelineError, FrameError) as err:
            r.fail("blend.rules" if rules else "blend.default", _strip_path(str(err)), err)


def _strip_path(message: str) -> str:
    """'poses.smile.AU99: msg' -> 'msg' (the Reader puts the path back in front)."""
    head, sep, rest = message.partition(": ")
    return rest if sep and " " not in head else message


def _first_path(message: str, default: str) -> str:
    head, sep, _ = message.partition(": ")
    return head if sep and " " not in head else default


__all__ = ["SCRIPTS_DIR", "Script", "ScriptError", "example_scripts", "load_script", "parse_script"]
