"""Recording a live tracker stream into keyframes (Author: "record a live stream").

The studio opens a stream input of its own (``controller/inputs``: UDP datagrams or TCP lines of AU frames,
the messages `servoface stream` takes), on loopback, and — unless told not to — the head follows it live
on the ``stream`` track, so the person sees what is being recorded. Every *accepted* message (decoded and
validated by the stream's own decoder; bad ones are counted and dropped) is kept with its time: the
sender's ``t`` when every message has one, else the arrival time. :func:`reduce_keys` turns the samples
into few keys: a key is kept where linear interpolation between the kept keys would miss any AU of any
sample by more than ``tolerance`` (Ramer-Douglas-Peucker over time, the largest deviation of all AUs), so
the keys played back with linear easing give the recorded AUs within ``tolerance``. Each key is a complete
pose (every AU the stream named; one it did not send in a message is 0 there, as in a frame)."""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from servoface.controller.studio.errors import ConflictError, InvalidValueError

MAX_SAMPLES = 36_000  # 20 minutes of a 30 Hz tracker; later messages are counted, not kept
DEFAULT_TOLERANCE = 0.01


@dataclass
class Sample:
    t_s: float | None  # the sender's time
    arrival_s: float
    aus: dict[str, float]


def _value(sample: dict[str, float], name: str) -> float:
    return float(sample.get(name, 0.0))


def reduce_keys(
    times_s: Sequence[float], frames: Sequence[dict[str, float]], tolerance: float
) -> list[tuple[float, dict[str, float]]]:
    """The fewest keys (a subset of the samples, the first and last always) whose linear interpolation
    is within ``tolerance`` of every AU of every sample. Iterative (no recursion limit)."""
    n = len(times_s)
    if n == 0:
        return []
    names = sorted({k for f in frames for k in f})
    if n == 1:
        return [(times_s[0], {k: _value(frames[0], k) for k in names})]
    keep = {0, n - 1}
    stack = [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        ta, tb = times_s[a], times_s[b]
        span = tb - ta
        worst, worst_i = -1.0, -1
        for i in range(a + 1, b):
            w = 0.0 if span <= 0 else (times_s[i] - ta) / span
            err = max(
                (abs(_value(frames[i], k) - (_value(frames[a], k) + w * (_value(frames[b], k) - _value(frames[a], k))))
                 for k in names),
                default=0.0,
            )  # fmt: skip
            if err > worst:
                worst, worst_i = err, i
        if worst > tolerance:
            keep.add(worst_i)
            stack.append((a, worst_i))
            stack.append((worst_i, b))
    return [(times_s[i], {k: round(_value(frames[i], k), 5) for k in names}) for i in sorted(keep)]


@dataclass
class StreamRecording:
    """One recording: the stream source, its receiver, the samples (see the module docstring)."""

    transport: str
    tolerance: float
    source: Any
    receiver: Any
    follow: Any = None  # the service command following the stream, if any
    samples: list[Sample] = field(default_factory=list)
    over: int = 0  # messages past MAX_SAMPLES
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_message(self, msg: Any, arrival_s: float) -> None:  # receiver thread
        with self.lock:
            if len(self.samples) >= MAX_SAMPLES:
                self.over += 1
                return
            self.samples.append(Sample(msg.t_s, float(arrival_s), dict(msg.aus)))

    @property
    def port(self) -> int:
        return int(self.receiver.address[1])

    def state(self) -> dict[str, Any]:
        stats = self.source.stats
        with self.lock:
            n = len(self.samples)
            span = self.samples[-1].arrival_s - self.samples[0].arrival_s if n > 1 else 0.0
        return {
            "active": True,
            "transport": self.transport,
            "host": "127.0.0.1",
            "port": self.port,
            "samples": n,
            "messages": stats.messages,
            "bad": stats.bad,
            "rate_limited": self.receiver.guard.stats.rate_limited,
            "errors": list(stats.errors)[-3:],
            "over": self.over,
            "duration_s": round(span, 4),
            "following": self.follow is not None,
        }

    def keys(self) -> dict[str, Any]:
        with self.lock:
            samples = list(self.samples)
        if not samples:
            return {"keys": [], "samples": 0, "time_base": "", "tolerance": self.tolerance, "duration_s": 0.0}
        by_sender = all(s.t_s is not None for s in samples)
        raw = [float(s.t_s if by_sender and s.t_s is not None else s.arrival_s) for s in samples]
        times: list[float] = []
        frames: list[dict[str, float]] = []
        for t, s in zip(raw, samples, strict=True):  # a sender whose clock went back: keep time moving on
            rel = t - raw[0]
            if times and rel <= times[-1]:
                rel = times[-1] + 1e-3
            times.append(rel)
            frames.append(s.aus)
        kept = reduce_keys(times, frames, self.tolerance)
        if len(kept) == 1:  # a keyframe clip needs its last key after 0
            kept.append((0.1, dict(kept[0][1])))
        keys = [{"t_s": round(t, 4), "pose": pose, "easing": "linear"} for t, pose in kept]
        return {
            "keys": keys,
            "samples": len(samples),
            "time_base": "sender" if by_sender else "arrival",
            "tolerance": self.tolerance,
            "duration_s": round(times[-1], 4),
        }

    def close(self) -> None:
        self.receiver.close()


def open_recording(head: Any, transport: str, port: int, tolerance: float) -> StreamRecording:
    """The stream source and its loopback receiver (started); refuses a port in use with a clear 409. The
    head's AU names and its own ranges are the decoder's (`MessageDecoder.for_head`): what is recorded is what
    the head can play back."""
    from servoface.controller.inputs.errors import InputError
    from servoface.controller.inputs.messages import MessageDecoder
    from servoface.controller.inputs.stream import StreamSource
    from servoface.controller.inputs.tcp_server import TcpReceiver
    from servoface.controller.inputs.transports import UdpReceiver

    if not 0.0 < tolerance <= 0.5:
        raise InvalidValueError(f"tolerance: expected 0 < tolerance <= 0.5, got {tolerance!r}", field="tolerance")
    holder: list[StreamRecording] = []
    source = StreamSource(
        MessageDecoder.for_head(head),
        on_message=lambda msg, arrival: holder[0].on_message(msg, arrival) if holder else None,
    )
    try:
        if transport == "udp":
            receiver: Any = UdpReceiver(source, "127.0.0.1", port)
        else:
            receiver = TcpReceiver(source, "127.0.0.1", port)
    except InputError as err:
        raise ConflictError(f"port: {err}", field="port") from err
    recording = StreamRecording(transport, float(tolerance), source, receiver)
    holder.append(recording)
    receiver.start()
    return recording
