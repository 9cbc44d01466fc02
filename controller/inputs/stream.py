"""A live face-data stream as a source: ``StreamSource.sample(t_s) -> AUFrame`` at the control loop's rate.

Receivers (transports.py) run on background threads and hand raw messages (bytes/str) to
:meth:`StreamSource.feed`, which decodes and validates them (messages.py) and keeps only the LATEST good
one with its arrival time (a latest-value buffer: a slow loop never works through a backlog, it skips to
now; a receiver that finds several messages waiting decodes only the newest and counts the others as
``superseded``). A bad message is counted, its error kept (``stats.errors``, the last 20) and dropped:
it never reaches the pipeline; one bad field rejects that message. A message older than the newest by its
own ``t`` (UDP reordering) is dropped as ``out_of_order``, unless its ``t`` is more than ``RESTART_S`` (1 s)
back or the stream is in dropout: then the sender restarted its clock and the message is taken
(``restarts``); one below ``min_confidence`` counts as no data.

``sample`` (called by the loop thread) applies, in order:

* dropout policy: if the newest good message is older than ``dropout_ms`` (default 250 ms) on the
  receiver clock, the stream is in dropout. ``dropout="neutral"`` (default) eases the last AUs linearly to
  neutral over ``ease_s`` (default 0.5 s); ``"hold"`` keeps them. Before the first message the face is
  neutral. Each newest message that goes stale counts one dropout (``stats.dropouts``).
* playout (optional, ``playout_ms`` > 0): the AUs are taken ``playout_ms`` in the past on the arrival
  clock, interpolated linearly between the two messages around that instant: a fixed extra latency that
  turns uneven arrival (Wi-Fi jitter, a 30 Hz sender sampled at 50 Hz) into even motion.
* smoothing: a One-Euro filter per AU (smoothing.py; ``smoothing=None`` switches it off).

``on_message(msg, arrival_s)`` sees every accepted message (e.g. :class:`StreamRecorder` writes them to a
JSON-lines file that ``servoface play --input`` replays, timed by the messages' own ``t``). The clock is injectable
(``clock() -> s``; default ``time.monotonic``): arrival stamps and dropout ages use it, so tests drive
time by hand.
"""

from __future__ import annotations

import json
import threading
import time
from collections import deque
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from servoface.controller.errors import FrameError
from servoface.controller.frame import AUFrame
from servoface.controller.inputs.admission import StreamGuard
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.head_pose import parse_head
from servoface.controller.inputs.messages import Message, MessageDecoder, parse_json
from servoface.controller.inputs.rest_pose import RestPose
from servoface.controller.inputs.smoothing import AUSmoother
from servoface.controller.loop import RunningStat

Clock = Callable[[], float]
RESTART_S = 1.0  # a message this much older than the newest (by its t) means the sender restarted


@dataclass
class StreamStats:
    """Counters of a stream (read them from any thread; they only grow)."""

    messages: int = 0  # raw messages received
    superseded: int = 0  # received but not decoded: a newer one arrived in the same read (no backlog)
    good: int = 0
    bad: int = 0
    out_of_order: int = 0
    restarts: int = 0  # messages whose t jumped back more than RESTART_S (or after a dropout): accepted
    low_confidence: int = 0
    dropouts: int = 0  # newest messages seen going stale by sample()
    samples: int = 0
    samples_in_dropout: int = 0
    calibrating: int = 0  # messages taken as the rest pose (rest_s), not shown
    rest: str = ""  # what the rest pose was
    latency_s_max: float = 0.0  # largest age of the newest message at a sample (outside dropouts)
    age_s: RunningStat = field(default_factory=RunningStat)  # age of the newest message at each fresh sample
    errors: deque[str] = field(default_factory=lambda: deque(maxlen=20))

    def summary(self) -> dict[str, Any]:
        return {
            "messages": self.messages,
            "good": self.good,
            "bad": self.bad,
            "out_of_order": self.out_of_order,
            "superseded": self.superseded,
            "restarts": self.restarts,
            "low_confidence": self.low_confidence,
            "dropouts": self.dropouts,
            "samples": self.samples,
            "samples_in_dropout": self.samples_in_dropout,
            "age_mean_ms": round(1e3 * self.age_s.mean, 2),
            "age_max_ms": round(1e3 * self.latency_s_max, 2),
            "last_errors": list(self.errors)[-5:],
        }


class StreamSource:
    """Latest-value buffer + dropout policy + smoothing over a message decoder (see the module doc)."""

    def __init__(
        self,
        decoder: MessageDecoder | None = None,
        *,
        dropout_ms: float = 250.0,
        dropout: str = "neutral",
        ease_s: float = 0.5,
        min_confidence: float = 0.0,
        smoothing: AUSmoother | None | str = "default",
        clock: Clock = time.monotonic,
        guard: StreamGuard | None = None,
        on_message: Callable[[Message, float], None] | None = None,
        playout_ms: float = 0.0,
        rest_s: float = 0.0,
    ) -> None:
        if dropout not in ("neutral", "hold"):
            raise InputError(f"dropout: expected 'neutral' or 'hold', got {dropout!r}")
        for name, value in (("dropout_ms", dropout_ms), ("ease_s", ease_s)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value < 1e6:
                raise InputError(f"{name}: expected a positive number, got {value!r}")
        if not (isinstance(min_confidence, int | float) and 0.0 <= min_confidence <= 1.0):
            raise InputError(f"min_confidence: expected 0..1, got {min_confidence!r}")
        self.decoder = decoder or MessageDecoder("human")
        self.face_type = self.decoder.face_type
        self.dropout_s = float(dropout_ms) / 1e3
        self.dropout = dropout
        self.ease_s = float(ease_s)
        self.min_confidence = float(min_confidence)
        if smoothing is not None and smoothing != "default" and not isinstance(smoothing, AUSmoother):
            raise InputError(f"smoothing: expected an AUSmoother, None or 'default', got {smoothing!r}")
        self.smoother: AUSmoother | None = AUSmoother() if isinstance(smoothing, str) else smoothing
        if isinstance(playout_ms, bool) or not isinstance(playout_ms, int | float) or not 0 <= playout_ms < 1e4:
            raise InputError(f"playout_ms: expected 0 <= playout < 10000 ms, got {playout_ms!r}")
        self.playout_s = float(playout_ms) / 1e3
        self._history: deque[tuple[float, Message]] = deque(maxlen=16)
        self.clock = clock
        self.on_message = on_message  # called (receiver thread, under the lock) with each accepted message
        self.guard = guard  # token, rate limits, control (admission.py); None = take every valid message
        if isinstance(rest_s, bool) or not isinstance(rest_s, int | float) or not 0.0 <= rest_s < 1e4:
            raise InputError(f"rest_s: expected 0 <= rest_s < 10000 s, got {rest_s!r}")
        self.rest_s = float(rest_s)
        self._rest_until: float | None = None
        self._rest_rows: list[tuple[dict[str, float], tuple[float, float, float] | None]] = []
        self.stats = StreamStats()
        self._lock = threading.Lock()
        self._latest: Message | None = None
        self._latest_arrival_s = 0.0
        self._dropped: Message | None = None  # the latest message whose going stale was counted
        self._lo, self._hi = self.decoder.validator.range

    # -- receiver side (any thread) ------------------------------------------------------------------
    def feed(
        self,
        raw: str | bytes,
        *,
        where: str = "message",
        client: Hashable = None,
        authenticated: bool = False,
        rate_checked: bool = False,
    ) -> bool:
        """Decode one raw message from ``client``; True if it became the latest value. Never raises, whatever
        ``raw`` holds. With a guard: rate limit, token (unless the connection already ``authenticated``) and
        the control rule apply, in that order."""
        admitted = self._admit(client, rate_checked)
        if admitted is None:
            return False
        arrival, index = admitted
        try:
            obj = parse_json(raw, where=f"{where} #{index}")
        except FrameError as err:
            self._bad(str(err))
            return False
        return self._take(obj, arrival, index, where, client, authenticated)

    def feed_obj(
        self,
        obj: Any,
        *,
        where: str = "message",
        client: Hashable = None,
        authenticated: bool = False,
        rate_checked: bool = False,
    ) -> bool:
        """:meth:`feed` for a message already parsed by ``parse_json`` (bounded size and depth), e.g. the
        body of a network envelope: no second serialise + parse per frame. Never raises."""
        admitted = self._admit(client, rate_checked)
        if admitted is None:
            return False
        arrival, index = admitted
        return self._take(obj, arrival, index, where, client, authenticated)

    def _admit(self, client: Hashable, rate_checked: bool) -> tuple[float, int] | None:
        """Count one message and apply the rate limit: its arrival time and index, or None if refused."""
        arrival = self.clock()
        with self._lock:
            self.stats.messages += 1
            index = self.stats.messages
        guard = self.guard
        if guard is not None and not rate_checked and not guard.rate_ok(client):
            return None
        return arrival, index

    def _take(self, obj: Any, arrival: float, index: int, where: str, client: Hashable, authenticated: bool) -> bool:
        guard = self.guard
        try:
            if guard is not None and not authenticated and not guard.token_ok(obj):
                return False
            msg = self.decoder.decode(obj, where=f"{where} #{index}")
        except FrameError as err:  # InputError is a FrameError
            self._bad(str(err))
            return False
        except Exception as err:  # noqa: BLE001 - a receiver must survive any single message
            self._bad(f"{where} #{index}: unreadable message ({type(err).__name__})")
            return False
        if guard is not None and not guard.claim(client):
            return False
        if self.rest_s > 0 and not self.stats.rest:
            if self._collect_rest(obj, arrival):
                return False
            msg = self.decoder.decode(obj, where=f"{where} #{index}")  # the window closed: with the rest pose
        return self.offer(msg, arrival)

    def _collect_rest(self, obj: Any, arrival: float) -> bool:
        """Rest-pose window (``rest_s`` from the first accepted message): True = collected, not shown; False
        = the window has passed (the rest pose is now set on the decoder)."""
        if self._rest_until is None:
            self._rest_until = arrival + self.rest_s
        if arrival <= self._rest_until:
            scores: dict[str, float] = {}
            head = None
            if self.decoder.face_type == "human":  # the message decoded: its fields are valid
                bmap = self.decoder.blendshape_map
                for name, value in (obj.get("blendshapes") or {}).items():
                    scores[bmap.resolve(name, field="rest")] = min(1.0, max(0.0, float(value)))
                head = parse_head(obj["head"]) if "head" in obj else None
            with self._lock:
                self._rest_rows.append((scores, head))
                self.stats.calibrating += 1
            return True
        rows = [(0.0, shapes, ypr, None) for shapes, ypr in self._rest_rows if shapes or ypr]
        if rows:
            rest = RestPose.from_rows(rows, 1.0)
            if rest.values:
                self.decoder.shape_ranges = rest.shape_ranges(self.decoder.shape_ranges)
            self.decoder.head_rest_deg = rest.head_deg
            self.stats.rest = rest.describe(self.rest_s)
        else:
            self.stats.rest = f"rest pose: no blendshapes or head pose in the first {self.rest_s:g} s"
        return False

    def _bad(self, error: str) -> None:
        with self._lock:
            self.stats.bad += 1
            self.stats.errors.append(error if len(error) <= 300 else error[:297] + "...")

    def admit(self, client: Hashable, count: int) -> bool:
        """``count`` raw messages arrived from ``client`` in one read and only the newest will be decoded:
        all are counted as received, the guard's rate limit takes its share, the rest of what fits is
        superseded. True if the newest is to be fed (with ``rate_checked=True``)."""
        allowed = count if self.guard is None else self.guard.take(client, count)
        with self._lock:
            self.stats.messages += count - (1 if allowed else 0)
            self.stats.superseded += max(0, allowed - 1)
        return allowed > 0

    def rate_ok(self, client: Hashable) -> bool:
        """The guard's rate limit for one raw message from ``client`` (counted as received if refused); a
        receiver that checks it itself passes ``rate_checked=True`` to :meth:`feed`."""
        if self.guard is None or self.guard.rate_ok(client):
            return True
        with self._lock:
            self.stats.messages += 1
        return False

    def supersede(self, count: int) -> None:
        """Count ``count`` messages a receiver dropped unread because a newer one was already waiting."""
        with self._lock:
            self.stats.messages += count
            self.stats.superseded += count

    def offer(self, msg: Message, arrival_s: float | None = None) -> bool:
        """Take an already decoded message (e.g. from a recording) as the latest value if it is newer."""
        arrival = self.clock() if arrival_s is None else arrival_s
        with self._lock:
            if msg.confidence < self.min_confidence:
                self.stats.low_confidence += 1
                return False
            latest = self._latest
            if latest is not None and msg.t_s is not None and latest.t_s is not None and msg.t_s < latest.t_s:
                stale = arrival - self._latest_arrival_s > self.dropout_s
                if not stale and latest.t_s - msg.t_s <= RESTART_S:
                    self.stats.out_of_order += 1
                    return False
                self.stats.restarts += 1  # the sender's clock went back: a restarted tracker, not reordering
            self.stats.good += 1
            self._latest, self._latest_arrival_s = msg, arrival
            self._history.append((arrival, msg))
            if self.on_message is not None:
                self.on_message(msg, arrival)
            return True

    # -- loop side -------------------------------------------------------------------------------------
    def target(self) -> tuple[dict[str, float], bool]:
        """The AUs the stream asks for now (dropout policy applied, not smoothed) and whether in dropout."""
        now = self.clock()
        with self._lock:
            latest, arrival = self._latest, self._latest_arrival_s
        if latest is None:
            return {}, True
        age = now - arrival
        if age <= self.dropout_s:
            self.stats.latency_s_max = max(self.stats.latency_s_max, age)
            self.stats.age_s.add(age)
            if self.playout_s > 0:
                return self._played_out(now - self.playout_s), False
            return dict(latest.aus), False
        if self.dropout == "hold":
            return dict(latest.aus), True
        k = max(0.0, 1.0 - (age - self.dropout_s) / self.ease_s)
        return {n: v * k for n, v in latest.aus.items()}, True

    def _played_out(self, when_s: float) -> dict[str, float]:
        """The AUs at ``when_s`` on the arrival clock, linear between the two messages around it."""
        with self._lock:
            history = list(self._history)
        before = [(a, m) for a, m in history if a <= when_s]
        after = [(a, m) for a, m in history if a > when_s]
        if not before:
            return dict(history[0][1].aus)
        if not after:
            return dict(before[-1][1].aus)
        (a0, m0), (a1, m1) = before[-1], after[0]
        w = (when_s - a0) / (a1 - a0) if a1 > a0 else 1.0
        names = set(m0.aus) | set(m1.aus)
        return {n: (1 - w) * m0.aus.get(n, 0.0) + w * m1.aus.get(n, 0.0) for n in names}

    def sample(self, t_s: float) -> AUFrame:
        """The frame for loop time ``t_s``: latest good AUs, dropout policy, smoothing; always valid."""
        aus, in_dropout = self.target()
        self.stats.samples += 1
        if in_dropout:
            self.stats.samples_in_dropout += 1
            latest = self._latest
            if latest is not None and latest is not self._dropped:
                self.stats.dropouts += 1
                self._dropped = latest
        if self.smoother is not None:
            aus = self.smoother(aus, self.clock())
        clean = {n: min(self._hi, max(self._lo, v)) for n, v in aus.items()}
        return AUFrame(t_s, clean, self.face_type, allowed=self.decoder.validator.allowed)


MAX_RECORD_GAP_S = 3600.0  # a later message t further ahead than this continues by arrival time


class StreamRecorder:
    """Writes accepted messages as JSON lines (``{"t": ..., "aus": {...}}``): a recording of what the robot
    was asked to do, replayable with ``read_jsonl`` / ``servoface play --input``. ``t`` keeps the messages'
    own times (from the first message's), so a file piped in faster than real time records at its own
    pace; a message without ``t``, or one whose ``t`` jumps back (a restarted sender) or more than an hour
    ahead (a sender's clock reset, or a ``t`` of 1e308 that would make the recording endless or ``Infinity``),
    continues by arrival time from the last line written: every line is JSON that ``play --input`` reads."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self._fh: IO[str] | None = self.path.open("w", encoding="utf-8")
        except OSError as err:
            raise InputError(f"{self.path}: cannot write the recording: {err}") from err
        self._origin: tuple[float, float] | None = None  # (message t, recording t) of the last anchor
        self._last_t = 0.0
        self._last_arrival: float | None = None
        self.count = 0

    def _time(self, msg: Message, arrival_s: float) -> float:
        by_arrival = self._last_t + (arrival_s - self._last_arrival if self._last_arrival is not None else 0.0)
        if msg.t_s is None:
            self._origin = None
            return by_arrival
        if self._origin is not None:
            t = self._origin[1] + (msg.t_s - self._origin[0])
            if self._last_t <= t <= self._last_t + MAX_RECORD_GAP_S:  # (not a jump of 1e308 s, nor to inf)
                return t
        self._origin = (msg.t_s, by_arrival)
        return by_arrival

    def __call__(self, msg: Message, arrival_s: float) -> None:
        if self._fh is None:
            return
        t = self._time(msg, arrival_s)
        self._last_t, self._last_arrival = t, arrival_s
        line = {"t": round(t, 6), "aus": {k: round(v, 6) for k, v in msg.aus.items()}}
        try:
            self._fh.write(json.dumps(line) + "\n")
        except ValueError:  # closed by the main thread while a receiver thread was still delivering
            return
        self.count += 1

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None
