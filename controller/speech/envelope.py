"""Any audio, no transcript: a causal loudness/spectral envelope -> jaw and lip opening and a rough mouth
class (closed / open / spread / rounded), usable live.

Per 10 ms hop, over a 25 ms window (only past samples: causal): RMS level in dB against a slowly tracked
noise floor gives the **opening** (an attack of ~15 ms, a release of ~60 ms, so syllables do not flutter);
the spectral centroid and the low-band share give the **class**: much energy above 3 kHz with little
below 1 kHz reads as a sibilant (spread, teeth together), a low centroid with strong low band as a rounded
vowel (oo, oh), else open. The latency is the window plus the attack: ~25-40 ms, which the plan's lead
can hide when the audio is delayed by the same amount (playback of a file) and which a live head shows.
Amplitude-driven jaws look like puppets when the jaw only flaps: the class adds lip shape to the jaw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.plan import LipSyncPlan, plan_from_features

HOP_S = 0.01
WINDOW_S = 0.025
ATTACK_S = 0.015
RELEASE_S = 0.06
RANGE_DB = 30.0  # from the noise floor + GATE_DB to full opening
GATE_DB = 8.0


@dataclass
class EnvelopeFollower:
    """Causal, frame-by-frame: feed audio hops with :meth:`push`, read features after each (live use)."""

    rate_hz: int
    floor_db: float = -70.0
    level: float = 0.0
    _tail: NDArray[np.float64] | None = None

    def push(self, hop: NDArray[np.float64]) -> dict[str, float]:
        """One hop of mono samples (-1..1) -> {"open", "part", "spread", "round"} for the latest 25 ms."""
        hop = np.asarray(hop, dtype=np.float64)
        win = int(WINDOW_S * self.rate_hz)
        buf = hop if self._tail is None else np.concatenate([self._tail, hop])
        self._tail = buf[-win:]
        frame = buf[-win:]
        rms = float(np.sqrt(np.mean(frame**2))) if len(frame) else 0.0
        db = 20.0 * np.log10(max(rms, 1e-7))
        # noise floor: follows quiet frames quickly, loud frames very slowly (rises 3 dB/s at most)
        if db < self.floor_db:
            self.floor_db = db
        else:
            self.floor_db += min(db - self.floor_db, 3.0 * HOP_S)
        target = float(np.clip((db - self.floor_db - GATE_DB) / RANGE_DB, 0.0, 1.0))
        tau = ATTACK_S if target > self.level else RELEASE_S
        self.level += (target - self.level) * (1.0 - np.exp(-HOP_S / tau))
        spread = round_ = 0.0
        if self.level > 0.05 and len(frame) >= 64:
            spectrum = np.abs(np.fft.rfft(frame * np.hanning(len(frame)))) ** 2
            freqs = np.fft.rfftfreq(len(frame), 1.0 / self.rate_hz)
            total = float(spectrum.sum()) or 1.0
            low = float(spectrum[freqs < 1000].sum()) / total
            high = float(spectrum[freqs > 3000].sum()) / total
            centroid = float((spectrum * freqs).sum()) / total
            if high > 0.45 and low < 0.3:
                spread = 1.0  # sibilant
            elif centroid < 900 and low > 0.7:
                round_ = 1.0  # rounded vowel
        opening = self.level * (0.35 if spread else 1.0)
        return {
            "open": opening * (0.7 if round_ else 0.85),
            "part": min(1.0, 0.2 + opening) if self.level > 0.05 else 0.0,
            "spread": 0.45 * spread * min(1.0, 2 * self.level),
            "round": 0.8 * round_ * min(1.0, 2 * self.level),
        }


def envelope_plan(samples: NDArray[np.float64], rate_hz: int, *, lead_s: float = 0.0) -> LipSyncPlan:
    """The envelope path over a whole recording (causal per hop, as live): a plan on the mouth clock."""
    if rate_hz <= 0:
        raise SpeechError(f"rate_hz: expected a positive sample rate, got {rate_hz}")
    x = np.asarray(samples, dtype=np.float64)
    hop = int(HOP_S * rate_hz)
    follower = EnvelopeFollower(rate_hz)
    n = len(x) // hop
    tracks: dict[str, list[float]] = {"open": [], "part": [], "spread": [], "round": []}
    for i in range(n):
        f = follower.push(x[i * hop : (i + 1) * hop])
        for k in tracks:
            tracks[k].append(f[k])
    # the features of hop i describe audio up to (i+1)*hop: that is their time on the audio clock
    times = (np.arange(n) + 1) * HOP_S
    # close at the end
    times = np.concatenate([times, [times[-1] + 0.1 if n else 0.1]])
    feats = {k: np.array([*v, 0.0]) for k, v in tracks.items()}
    times_s = np.asarray(times, dtype=np.float64)
    return plan_from_features(times_s, feats, audio_duration_s=len(x) / rate_hz, lead_s=lead_s)
