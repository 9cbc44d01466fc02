"""Sound output for a talking head, and the clock the mouth follows: the audio device's, or the monotonic.

**Which clock is master.** Where a sound device plays the speech, the *device* is the master clock: its
sample clock (a crystal on the sound card, not the machine's clock) decides when each sample comes out of
the speaker, and the mouth follows it. PortAudio reports, with every buffer it asks for, when that buffer's
first sample reaches the DAC (``outputBufferDacTime``, on the stream's clock; converted to the monotonic
clock by the offset between the stream's ``currentTime`` and ``time.monotonic()`` read in the same
callback). :class:`DeviceAudioClock` keeps the latest such anchor — "sample ``n`` plays at monotonic
``m``" — so the audio position at any monotonic time is ``n / rate + (m_now - m)``, re-anchored every buffer
(5-20 ms): a device whose crystal runs fast or slow, or that started late, drags the mouth with it.

Where there is no device (writing the WAV only, or ``audio_out=False``), :class:`MonotonicAudioClock` is
the master: the sound "plays" at its scheduled monotonic start, sample for sample.

:class:`AudioClockedClip` wraps the speech clip for the head service's speech track: at service-local time
``t`` the frame reaches the wire ``latency_s`` later, so it shows the mouth for where the sound is *then*
(the audio position at ``t0 + t + latency`` plus the plan's lead). With the monotonic clock that is the
clip's own time exactly; with a device it is the device's.

``sounddevice`` (PortAudio) is optional: ``pip install sounddevice`` and a sound card.
"""

from __future__ import annotations

import math
import threading
import time
import weakref
from collections import deque
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

ANCHORS_KEPT = 4096


class AudioClock(Protocol):
    name: str

    def position_s(self, monotonic_s: float) -> float | None:
        """Where the sound is (seconds into the buffer) at ``monotonic_s``; None: not known yet."""
        ...


@dataclass
class MonotonicAudioClock:
    """The sound plays at ``start_monotonic_s``, sample for sample on the monotonic clock (no device)."""

    start_monotonic_s: float
    name: str = "monotonic"

    def position_s(self, monotonic_s: float) -> float | None:
        return monotonic_s - self.start_monotonic_s


class DeviceAudioClock:
    """The audio device's clock, from PortAudio's per-buffer DAC times (see the module doc). Until the
    first buffer is reported it answers with the schedule (``scheduled_start_monotonic_s``)."""

    name = "device"

    def __init__(self, rate_hz: int, scheduled_start_monotonic_s: float) -> None:
        self.rate_hz = int(rate_hz)
        self.scheduled_start_monotonic_s = float(scheduled_start_monotonic_s)
        self._lock = threading.Lock()
        self._anchor: tuple[float, float] | None = None  # (position s, monotonic time it plays)
        self.anchors: deque[tuple[float, float]] = deque(maxlen=ANCHORS_KEPT)

    def anchor(self, frames_done: int, dac_monotonic_s: float) -> None:
        """Sample ``frames_done`` of the buffer reaches the DAC at ``dac_monotonic_s`` (callback thread)."""
        if not (math.isfinite(dac_monotonic_s) and frames_done >= 0):
            return
        pos = frames_done / self.rate_hz
        with self._lock:
            self._anchor = (pos, float(dac_monotonic_s))
            self.anchors.append(self._anchor)

    def position_s(self, monotonic_s: float) -> float | None:
        with self._lock:
            anchor = self._anchor
        if anchor is None:
            return monotonic_s - self.scheduled_start_monotonic_s
        pos, at = anchor
        return pos + (monotonic_s - at)

    def offsets_s(self) -> list[float]:
        """Per anchor: how far the device is behind its schedule (+: the sound is later than planned)."""
        with self._lock:
            anchors = list(self.anchors)
        return [at - (self.scheduled_start_monotonic_s + pos) for pos, at in anchors]


@dataclass
class AudioClockedClip:
    """The speech clip timed by ``clock`` (see the module doc). Looks like a timeline clip to the head
    service (``duration_s``, ``holds``, ``sample``, ``targets``, ``end_pose``); past the inner clip's end it
    provides nothing (the face track has the mouth back)."""

    clip: Any
    clock: AudioClock
    t0_monotonic_s: float
    latency_s: float
    audio_start_s: float
    duration_s: float
    name: str = "speech"
    holds: bool = False
    shifts: deque[float] = field(default_factory=lambda: deque(maxlen=ANCHORS_KEPT))  # mouth time - clip time

    def mouth_time_s(self, local_s: float) -> float:
        pos = self.clock.position_s(self.t0_monotonic_s + local_s + self.latency_s)
        mouth = local_s if pos is None else pos + self.audio_start_s
        self.shifts.append(mouth - local_s)
        return mouth

    def sample(self, local_s: float, from_pose: Mapping[str, float]) -> Mapping[str, float]:
        mouth = self.mouth_time_s(local_s)
        if mouth >= self.clip.duration_s:
            return {}
        pose: Mapping[str, float] = self.clip.sample(max(0.0, mouth), from_pose)
        return pose

    def targets(self) -> Iterator[tuple[str, float]]:
        return iter(self.clip.targets())

    def end_pose(self, from_pose: Mapping[str, float]) -> dict[str, float]:
        return {}


STOP_POLL_S = 0.02  # how often the sound thread looks for a stop (a stop is silent within this + a buffer)
_ENDED = ("cancelled", "failed")  # a command's statuses (service.handles.Status) that end its sound


@dataclass(eq=False)  # hashable by identity: kept in a WeakSet while it plays
class AudioOut:
    """Plays one buffer on the default output, started at a monotonic time; ``available`` False means no
    device (silent).

    **Stopping.** :meth:`stop` (any thread) ends the sound at once: the callback outputs silence and raises
    ``CallbackAbort``, the stream is aborted (PortAudio drops what is queued) and closed; a sound not
    started yet never starts. :meth:`stop_with` ties the sound to a head service command (the utterance's
    speech command, a script's face command): when that command is cancelled or fails — a stop, Ctrl-C,
    an e-stop, a torque-off, the service's shutdown (`Face.close`, the safe stop), a newer utterance taking
    the speech track — the sound stops with the mouth; ``owner`` (the head service) stopping does too."""

    available: bool
    reason: str = ""
    owner: Any = None
    _thread: threading.Thread | None = None
    _done: threading.Event = field(default_factory=threading.Event)
    _stop: threading.Event = field(default_factory=threading.Event)
    _with: list[Any] = field(default_factory=list)

    def stop(self) -> None:
        """End the sound now (silent within one poll and one buffer); safe to call twice, from any thread."""
        self._stop.set()

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def stop_with(self, handle: Any) -> None:
        """Stop the sound when ``handle`` (a head service CommandHandle) is cancelled or fails."""
        self._with.append(handle)

    def _should_stop(self) -> bool:
        if self._stop.is_set():
            return True
        owner_gone = self.owner is not None and getattr(self.owner, "running", True) is False
        if owner_gone or any(str(h.status) in _ENDED for h in list(self._with)):
            self._stop.set()
            return True
        return False

    def play_at(self, samples: NDArray[np.float64], rate_hz: int, start_monotonic_s: float) -> AudioClock:
        """Start ``samples`` so that the first reaches the speaker at ``start_monotonic_s``; returns the
        clock the mouth should follow (the device's; the monotonic one when silent). Non-blocking."""
        if not self.available:
            return MonotonicAudioClock(start_monotonic_s)
        clock = DeviceAudioClock(rate_hz, start_monotonic_s)
        data = np.asarray(samples, dtype=np.float32).reshape(-1)
        _PLAYING.add(self)

        def run() -> None:
            import sounddevice

            done = [0]

            def callback(outdata: Any, frames: int, time_info: Any, status: Any) -> None:
                if self._stop.is_set():
                    outdata.fill(0)
                    raise sounddevice.CallbackAbort
                n = done[0]
                chunk = data[n : n + frames]
                outdata[: len(chunk), 0] = chunk
                outdata[len(chunk) :, 0] = 0.0
                now = time.monotonic()
                clock.anchor(n, now + (time_info.outputBufferDacTime - time_info.currentTime))
                done[0] = n + frames
                if n + frames >= len(data):
                    raise sounddevice.CallbackStop

            try:
                stream = sounddevice.OutputStream(  # opened, not started
                    samplerate=rate_hz, channels=1, dtype="float32", callback=callback, finished_callback=self._done.set
                )
                try:
                    start_at = start_monotonic_s - float(stream.latency)
                    while not self._should_stop() and time.monotonic() < start_at:
                        time.sleep(min(STOP_POLL_S, max(0.0, start_at - time.monotonic())))
                    if self._stop.is_set():
                        self.reason = f"{self.reason}; stopped before it started".lstrip("; ")
                        return
                    stream.start()
                    give_up = time.monotonic() + len(data) / rate_hz + 5.0
                    while not self._done.wait(STOP_POLL_S) and time.monotonic() < give_up:
                        if self._should_stop():
                            break
                    if self._stop.is_set():  # (the callback may have raised CallbackAbort already)
                        stream.abort()
                        self.reason = f"{self.reason}; stopped at {done[0] / rate_hz:.2f} s".lstrip("; ")
                finally:
                    stream.close()
            except Exception as err:  # noqa: BLE001 - a device that fails mid-way: the mouth keeps its schedule
                self.reason = f"sound output failed ({type(err).__name__}: {err})"
            finally:
                self._done.set()
                _PLAYING.discard(self)

        self._thread = threading.Thread(target=run, name="servoface-audio", daemon=True)
        self._thread.start()
        return clock

    def wait(self, timeout_s: float = 60.0) -> None:
        if self._thread is not None:
            self._thread.join(timeout_s)


_PLAYING: weakref.WeakSet[AudioOut] = weakref.WeakSet()


def stop_sounds(owner: Any = None) -> int:
    """Stop every sound playing (for ``owner``, a head service, only; None: all of this process's): how
    many. `Face.close` calls it, so no sound outlives the face that spoke it."""
    outs = [o for o in list(_PLAYING) if owner is None or o.owner is owner]
    for out in outs:
        out.stop()
    return len(outs)


def open_audio_out(owner: Any = None) -> AudioOut:
    """An output on the default sound device (``owner``: the head service it speaks for, see
    :class:`AudioOut`), or a silent one saying why not."""
    try:
        import sounddevice
    except (ImportError, OSError) as err:
        return AudioOut(False, f"no sound output (sounddevice/PortAudio not available: {err})", owner)
    try:
        device = sounddevice.query_devices(kind="output")
    except Exception as err:  # PortAudio raises its own error type when there is no device  # noqa: BLE001
        return AudioOut(False, f"no sound output device ({err})", owner)
    return AudioOut(True, f"sound on {device.get('name', 'default output')}", owner)
