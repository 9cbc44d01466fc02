"""``HeadNode``: one head service on one Zenoh session (see :mod:`.keys` for what it serves).

Safety on the network:
- every message is opened by :func:`.messages.open_envelope` (size, depth, schema version) and checked
  against the sender's sequence; every value is validated by the head service (a bad command raises there
  and changes nothing); refusals are counted by reason and published on ``state/counters``;
- AU streams are followed through a ``StreamSource`` with its dropout policy: when frames stop, the track
  eases to neutral (250 ms + 0.5 s);
- when the link to a peer that holds **live control** drops (a controller that streams AU frames, or sent
  a command with ``"live": true``, and dies or is cut off), the head eases to neutral (0.3 s) unless
  ``hold_on_link_loss``; detection takes one lease (400 ms) at most. One-shot commands (a cue, an
  expression from ``servoface cue``) outlive the client that sent them: it may exit right after;
- an e-stop from any peer that can open a session (i.e. has the credentials) is honoured at once.
"""

from __future__ import annotations

import functools
import json
import math
import queue
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from servoface.controller.network.errors import MessageError
from servoface.controller.network.keys import TRACK_NAMES, VERBS, HeadKeys
from servoface.controller.network.messages import SCHEMA_VERSION, SequenceGuard, envelope, open_envelope

LINK_POLL_S = 0.05
LINK_LOSS_EASE_S = 0.3  # lease 0.4 s + 2 polls + this: at neutral within 1 s of the cut
SLOW_QUEUE = 4  # say commands waiting for synthesis (more are refused: "say refused (busy)")
CUE_WINDOW_S = (-0.5, 120.0)  # a cue may start at most this far in the past / future of the node's clock


# the keys each command takes (besides the envelope's schema, seq, from, live); any other is refused, naming it
COMMAND_KEYS: dict[str, tuple[str, ...]] = {
    "express": ("name", "intensity", "transition_s", "hold_s", "track"),
    "play": ("name", "track"),
    "look_at": ("point_mm",),
    "neutral": ("transition_s",),
    "stop": ("track",),
    "clear_estop": (),
    "say": ("text",),
    "cue": ("what", "at_s", "cue", "offset_s"),
}


def check_keys(verb: str, body: dict[str, Any]) -> None:
    """MessageError naming the first key of ``body`` that command ``verb`` does not take."""
    allowed = COMMAND_KEYS.get(verb, ())
    for key in body:
        if key not in allowed:
            expected = ", ".join(allowed) or "no fields"
            raise MessageError(f"{verb}.{str(key)[:40]}: unknown key; expected {expected}")


def needs_synthesis(verb: str, body: dict[str, Any]) -> bool:
    """Whether a command synthesises speech (``say``, a ``play`` of a shipped script that speaks, or a ``cue``
    whose ``what`` is one of those): those run on the node's slow worker, never on Zenoh's callback thread."""
    if verb == "say":
        return True
    if verb == "play":
        return speaking_shipped_script(body.get("name"))
    what = body.get("what") if verb == "cue" else None
    return isinstance(what, dict) and what.get("verb") in ("say", "play") and needs_synthesis(str(what["verb"]), what)


@functools.lru_cache(maxsize=64)
def _speaks_text(path: str, mtime_ns: int) -> bool:
    import tomllib

    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False  # the play itself reports the error
    plays = data.get("play", [])
    head = data.get("script", {})
    cues = isinstance(plays, list) and any(isinstance(p, dict) and "say" in p for p in plays)
    return cues or (isinstance(head, dict) and bool(head.get("audio")))


def speaking_shipped_script(name: object) -> bool:
    """True when ``name`` is a shipped script with say cues or a sound file (read as TOML only: cheap, no
    synthesis), played with its speech (:mod:`servoface.controller.speech.script_play`)."""
    from servoface.controller.shipped import is_shipped_script, resolve_script

    if not isinstance(name, str) or not is_shipped_script(name):
        return False
    path = resolve_script(name)
    try:
        return _speaks_text(str(path), path.stat().st_mtime_ns)
    except OSError:
        return False


class HeadNode:
    """Serve ``service`` (a running ``HeadService``) on ``session`` under ``keys``."""

    def __init__(
        self,
        service: Any,
        session: Any,
        keys: HeadKeys,
        *,
        frame_hz: float = 10.0,
        telemetry_hz: float = 5.0,
        hold_on_link_loss: bool = False,
        dropout_ms: float = 250.0,
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        self.service = service
        self.session = session
        self.keys = keys
        self.frame_hz = frame_hz
        self.telemetry_hz = telemetry_hz
        self.hold_on_link_loss = hold_on_link_loss
        self.dropout_ms = dropout_ms
        self.guard = SequenceGuard()
        self.link_losses = 0
        self.cues: list[dict[str, Any]] = []
        self._streams: dict[str, Any] = {}
        self._live: dict[str, float] = {}  # sender (its Zenoh session id) -> last live message (monotonic)
        self._seq = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._on_event = on_event or (lambda _msg: None)
        self._declared: list[Any] = []
        self._threads: list[threading.Thread] = []
        self._slow: queue.Queue[tuple[str, dict[str, Any]]] = queue.Queue(maxsize=SLOW_QUEUE)

    # -- life ---------------------------------------------------------------------------------------
    def start(self) -> HeadNode:
        s, k = self.session, self.keys
        self._declared += [
            s.declare_subscriber(k.aus_any, self._on_aus),
            s.declare_subscriber(k.cmd_any, self._on_cmd),
            s.declare_queryable(k.status, self._on_status),
            s.declare_queryable(k.clock, self._on_clock),
            s.liveliness().declare_token(k.presence),
        ]
        for target, name in ((self._publish_state, "state"), (self._watch_links, "links"), (self._run_slow, "say")):
            t = threading.Thread(target=target, name=f"servoface-node-{name}", daemon=True)
            t.start()
            self._threads.append(t)
        return self

    def close(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(2.0)
        for d in reversed(self._declared):
            try:
                d.undeclare()
            except Exception:  # noqa: BLE001 - the session may already be closing
                pass
        self._declared.clear()
        for source in self._streams.values():
            source.close()

    # -- helpers ------------------------------------------------------------------------------------
    def _next_seq(self) -> int:
        with self._lock:
            self._seq += 1
            return self._seq

    def _put(self, key: str, body: dict[str, Any]) -> None:
        try:
            self.session.put(key, envelope(body, self._next_seq()))
        except Exception:  # noqa: BLE001 - publishing must never take the node down
            pass

    def _open(self, sample: Any) -> tuple[str, dict[str, Any]] | None:
        key = str(sample.key_expr)
        try:
            seq, body = open_envelope(sample.payload.to_bytes())
        except MessageError as err:
            reason = str(err).split(":", 1)[0]
            self.guard.refuse(f"bad message ({reason})")
            return None
        sender = body.pop("from", None)
        if not isinstance(sender, str) or len(sender) > 64:
            sender = "?"
        live = body.pop("live", False) is True or "/aus/" in key
        if not self.guard.take(sender, key, seq):
            return None
        if live and sender != "?":
            with self._lock:
                self._live[sender] = time.monotonic()
        return key, body

    # -- AU streams ---------------------------------------------------------------------------------
    def _on_aus(self, sample: Any) -> None:
        opened = self._open(sample)
        if opened is None:
            return
        key, body = opened
        track = key.rsplit("/", 1)[-1]
        if track not in TRACK_NAMES:
            self.guard.refuse("unknown track")
            return
        source = self._stream(track)
        if source is None:
            return
        if not source.feed_obj(body, where=key, rate_checked=True):  # parsed once, by open_envelope
            self.guard.refuse("bad AU frame")

    def _stream(self, track: str) -> Any:
        with self._lock:
            source = self._streams.get(track)
            if source is not None:
                return source
            from servoface.controller.inputs import StreamSource
            from servoface.controller.inputs.messages import MessageDecoder

            source = StreamSource(MessageDecoder.for_head(self.service.head), dropout_ms=self.dropout_ms)
            self._streams[track] = source
        try:
            self.service.follow(source, track=track)
        except Exception as err:  # noqa: BLE001 - an unknown track on this head
            self.guard.refuse(f"follow refused ({type(err).__name__})")
            with self._lock:
                self._streams.pop(track, None)
            return None
        return source

    # -- commands -----------------------------------------------------------------------------------
    def _on_cmd(self, sample: Any) -> None:
        opened = self._open(sample)
        if opened is None:
            return
        key, body = opened
        verb = key.rsplit("/", 1)[-1]
        if verb not in VERBS:
            self.guard.refuse("unknown command")
            return
        if needs_synthesis(verb, body):  # ~0.1 s: not on Zenoh's callback thread (AU frames wait behind it)
            try:
                self._slow.put_nowait((verb, body))
            except queue.Full:
                self.guard.refuse("say refused (busy)")
            return
        self._command(verb, body)

    def _command(self, verb: str, body: dict[str, Any]) -> None:
        try:
            self.run_command(verb, body)
        except Exception as err:  # noqa: BLE001 - a refused command is counted and reported, never fatal
            self.guard.refuse(f"{verb} refused")
            refusal = {"verb": verb, "error": str(err)[:300]}
            if verb == "cue":  # which cue: its sender waits for each head's answer (`HeadsClient.cue_answers`)
                refusal["cue"] = str(body.get("cue", ""))[:64]
            self._put(self.keys.state("refused"), refusal)

    def _run_slow(self) -> None:
        while not self._stop.is_set():
            try:
                verb, body = self._slow.get(timeout=0.1)
            except queue.Empty:
                continue
            self._command(verb, body)

    def run_command(self, verb: str, body: dict[str, Any], *, at_s: float | None = None) -> Any:
        """Apply one command (already opened); raises the service's typed error for a bad value, and
        MessageError for a key the command does not have (a misspelt ``intensty`` must not play at full
        intensity)."""
        svc = self.service
        if verb == "estop":  # never refused, whatever else it carries
            return svc.estop(str(body.get("reason", "remote e-stop"))[:200])
        check_keys(verb, body)
        if verb == "clear_estop":
            return svc.clear_estop()
        if verb == "neutral":
            return svc.neutral(transition_s=body.get("transition_s", 0.6))
        if verb == "stop":
            return svc.stop(body.get("track", "face"))
        if verb == "express":
            return svc.express(
                body.get("name"),
                intensity=body.get("intensity", 1.0),
                transition_s=body.get("transition_s", 0.5),
                hold_s=body.get("hold_s", 1.0),
                track=body.get("track", "face"),
                at_s=at_s,
            )
        if verb == "play":
            name = body.get("name")
            if not isinstance(name, str):
                raise MessageError(f"play: name must be a shipped script or expression name, got {name!r:.40}")
            from servoface.controller.shipped import is_shipped_script

            if not is_shipped_script(name):  # an expression of the head's library, played as a clip
                from servoface.controller.timeline.library import library_clip

                return svc.play(library_clip(svc.head.face_type, name), track=body.get("track", "face"), at_s=at_s)
            if speaking_shipped_script(name):  # its say cues / sound file spoken as everywhere else
                return self._play_speaking(name, body.get("track", "face"), at_s)
            return svc.play(name, track=body.get("track", "face"), at_s=at_s)
        if verb == "look_at":
            point = body.get("point_mm")
            if point is not None and not isinstance(point, list):
                raise MessageError(f"look_at.point_mm: expected [x, y, z] in mm or null, got {point!r:.40}")
            return svc.look_at(None if point is None else tuple(point), at_s=at_s)
        if verb == "say":
            return self._say(body, at_s)
        if verb == "cue":
            return self._cue(body)
        raise MessageError(f"unknown command {verb!r}")

    def _say(self, body: dict[str, Any], at_s: float | None) -> Any:
        """Speak ``text`` on the speech track as `Face.say` does (:func:`~servoface.controller.speech.say.
        schedule_speech`: the head's jaw budget, the sound on this machine's output, the mouth on its clock,
        crossfaded from the face track's mouth)."""
        from servoface.controller.au_names import head_au_names
        from servoface.controller.speech.lipsync import speech_from_text
        from servoface.controller.speech.say import START_AHEAD_S, schedule_speech, service_latency_s
        from servoface.controller.speech.visemes import mouth_aus

        text = body.get("text")
        if not isinstance(text, str) or not text.strip() or len(text) > 2000:
            raise MessageError("say: text must be a non-empty string of at most 2000 characters")
        speech = speech_from_text(text)
        svc = self.service
        start = svc.now_s() + START_AHEAD_S if at_s is None else at_s
        allowed = head_au_names(svc.head) & mouth_aus(svc.head.face_type)
        under = svc.status().tracks.get("face")
        base = {au: v for au, v in (under.aus if under is not None else {}).items() if au in allowed}
        return schedule_speech(svc, speech, start, base=base, latency_s=service_latency_s(svc)).handle

    def _play_speaking(self, name: str, track: Any, at_s: float | None) -> Any:
        from servoface.controller.script import load_script
        from servoface.controller.speech.script_play import submit_script_speaking

        script = load_script(name, library=self.service.head.expressions_path)
        if script.face_type != self.service.head.face_type:
            raise MessageError(
                f"play: {name} is for a {script.face_type} face; this head is {self.service.head.face_type}"
            )
        handle, _ = submit_script_speaking(self.service, script, track=track, at_s=at_s)  # bad track: raises first
        return handle

    def _cue(self, body: dict[str, Any]) -> Any:
        what = body.get("what")
        at = body.get("at_s")
        if not isinstance(what, dict) or what.get("verb") not in ("express", "play", "look_at", "say", "neutral"):
            raise MessageError("cue: what must be {verb: express|play|look_at|say|neutral, ...}")
        if isinstance(at, bool) or not isinstance(at, int | float) or not math.isfinite(at):
            raise MessageError(f"cue: at_s must be a time on this head's clock, got {at!r:.40}")
        now = self.service.now_s()
        if not CUE_WINDOW_S[0] <= at - now <= CUE_WINDOW_S[1]:
            raise MessageError(f"cue: at_s {at:.10g} is {at - now:+.4g} s from now; expected within {CUE_WINDOW_S}")
        args = {k: v for k, v in what.items() if k != "verb"}
        handle = self.run_command(str(what["verb"]), args, at_s=float(at))
        record = {
            "cue": str(body.get("cue", ""))[:64],
            "at_s": float(at),
            "at_monotonic_s": self.service.clock.to_monotonic_s(float(at)),
            "offset_s": body.get("offset_s"),
            "received_ahead_s": round(at - now, 4),
        }
        self.cues.append(record)
        self._put(self.keys.state("cue"), record)
        self._on_event(f"cue {record['cue']} at {at:.3f} (offset {record['offset_s']})")
        return handle

    # -- queryables ---------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        svc = self.service
        st = svc.status()
        head = svc.head
        from servoface.controller.au_names import head_au_names
        from servoface.sim.expressions import load_library

        try:
            expressions = sorted(load_library(head.expressions_path or head.face_type))
        except Exception:  # noqa: BLE001 - a profile without a library
            expressions = []
        return {
            "schema": SCHEMA_VERSION,
            "site": self.keys.site,
            "name": self.keys.name,
            "head": head.name,
            "face_type": head.face_type,
            "aus": sorted(head_au_names(head)),
            "expressions": expressions,
            "servos": [{"id": a.servo.id, "role": a.role, "model": a.servo.model} for a in head.actuators],
            "tracks": sorted(st.tracks),
            "t_s": round(st.t_s, 4),
            "running": st.running,
            "estop_latched": st.estop_latched,
            "torque_on": st.torque_on,
            "frames": st.frames,
            "late": st.late,
            "link_losses": self.link_losses,
            "counters": self.guard.counters(),
        }

    def _on_status(self, query: Any) -> None:
        try:
            query.reply(self.keys.status, json.dumps(self.status()).encode())
        except Exception:  # noqa: BLE001 - a querier that went away
            pass

    def _on_clock(self, query: Any) -> None:
        try:
            body = {"service_s": self.service.now_s(), "monotonic_s": time.monotonic()}
            query.reply(self.keys.clock, json.dumps(body).encode())
        except Exception:  # noqa: BLE001
            pass

    # -- background ---------------------------------------------------------------------------------
    def _publish_state(self) -> None:
        svc = self.service
        frames = svc.subscribe("frame", rate_hz=self.frame_hz, maxlen=8)
        telemetry = svc.subscribe("telemetry", rate_hz=self.telemetry_hz, maxlen=4)
        faults = svc.subscribe("fault", maxlen=64)
        last_counters = 0.0
        try:
            while not self._stop.is_set():
                item = frames.get(timeout_s=0.05)
                if item is not None:
                    self._put(self.keys.state("frame"), item.as_dict())
                for snap in telemetry.drain():
                    self._put(self.keys.state("telemetry"), _jsonable(snap))
                for event in faults.drain():
                    self._put(self.keys.state("fault"), _jsonable(event))
                now = time.monotonic()
                if now - last_counters >= 1.0:
                    last_counters = now
                    self._put(self.keys.state("counters"), {**self.guard.counters(), "link_losses": self.link_losses})
        finally:
            for sub in (frames, telemetry, faults):
                sub.close()

    def _watch_links(self) -> None:
        missing: dict[str, int] = {}
        while not self._stop.wait(LINK_POLL_S):
            try:
                peers = {str(z) for z in self.session.info.peers_zid()}
            except Exception:  # noqa: BLE001 - session closing
                return
            with self._lock:
                live = list(self._live)
            lost = []
            for sender in live:
                if sender in peers:
                    missing.pop(sender, None)
                    continue
                missing[sender] = missing.get(sender, 0) + 1
                if missing[sender] >= 2:
                    lost.append(sender)
            if not lost:
                continue
            with self._lock:
                for sender in lost:
                    self._live.pop(sender, None)
                    missing.pop(sender, None)
            self.link_losses += 1
            self._on_event(f"link lost to controller(s) {', '.join(s[:8] for s in lost)}")
            if not self.hold_on_link_loss:
                self._ease_to_neutral()

    def _ease_to_neutral(self) -> None:
        with self._lock:
            streams, self._streams = self._streams, {}
        for source in streams.values():  # the next frame from a returning sender follows afresh
            source.close()
        try:
            self.service.neutral(transition_s=LINK_LOSS_EASE_S)
        except Exception:  # noqa: BLE001 - e.g. e-stop latched: already safe
            pass


def _jsonable(obj: Any) -> dict[str, Any]:
    if hasattr(obj, "as_dict"):
        out = obj.as_dict()
        return out if isinstance(out, dict) else {"value": out}
    if hasattr(obj, "__dict__"):
        return {k: v if isinstance(v, int | float | str | bool | type(None)) else repr(v) for k, v in vars(obj).items()}
    return {"value": repr(obj)}
