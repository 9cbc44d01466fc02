"""Timed visemes (or a loudness envelope) -> a lip-sync plan: mouth features over time -> AU keyframes.

- **Coarticulation** (Cohen & Massaro 1993 dominance functions): every viseme segment pulls the mouth
  towards its shape with a dominance that peaks at its centre and decays with distance (in units of its own
  duration); the mouth is the dominance-weighted mean of the shapes near it. Vowels spread onto their
  neighbouring consonants, low-dominance consonants (k, t, n) take the vowels' shape.
- **Bilabial closure**: inside every p/b/m segment the lips close (jaw and lip part to 0, press on) whatever
  the neighbours want — a talking head that does not close for "m" reads as dubbed.
- **Lead**: the mouth runs ``lead_s`` ahead of the sound (default 50 ms: the lips move before the sound
  they shape). The plan's clock is the *mouth* clock; the audio starts at ``audio_start_s = lead_s``.
- **Loudness**: jaw and lip opening scale with the audio's RMS (quiet syllables open less).
- **End**: after the last spoken segment the mouth is at neutral within ``close_s`` (default 0.1 s), and
  the clip then stops providing the mouth AUs (the face track takes them back).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.timing import TimedViseme
from servoface.controller.speech.visemes import FEATURES, VISEME_SHAPES, recipe_matrix
from servoface.controller.timeline.clip import ChannelClip, Key

PLAN_RATE_HZ = 100.0
DEFAULT_LEAD_S = 0.05
DEFAULT_CLOSE_S = 0.1
_THETA = 2.2  # dominance decay per (half) segment duration
_MIN_HALF_S = 0.035


@dataclass(frozen=True)
class LipSyncPlan:
    """Mouth features sampled on the mouth clock: ``times_s`` (n,), ``features`` (n, len(FEATURES)) in 0..1."""

    times_s: NDArray[np.float64]
    features: NDArray[np.float64]
    audio_start_s: float  # the sound starts this long after the mouth clock's 0 (= the lead)
    audio_duration_s: float
    segments: tuple[TimedViseme, ...] = ()
    #: per sample, how present the speech is (0..1): ramps in before the first spoken segment and out over
    #: ``close_s`` after the last (None: all 1, e.g. the envelope path). A clip over a face whose own mouth
    #: is not at rest (an expression held while talking) crossfades from and back to that mouth with it.
    presence: NDArray[np.float64] | None = None

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1]) if len(self.times_s) else 0.0

    @property
    def audio_end_s(self) -> float:
        return self.audio_start_s + self.audio_duration_s

    def feature(self, name: str) -> NDArray[np.float64]:
        return self.features[:, FEATURES.index(name)]

    def au_matrix(self, face_type: str, allowed: frozenset[str] | None = None) -> tuple[list[str], NDArray[np.float64]]:
        """(AU names, values (n, len(names))): the mouth on a face of ``face_type``, clamped to its range."""
        names, matrix = recipe_matrix(face_type, allowed)
        lo = -1.0 if face_type == "dog" else 0.0
        return names, np.clip(self.features @ matrix, lo, 1.0)

    def aus(self, face_type: str, allowed: frozenset[str] | None = None) -> list[dict[str, float]]:
        """Per sample, the AU intensities of the mouth on a face of ``face_type``."""
        names, values = self.au_matrix(face_type, allowed)
        return [dict(zip(names, row.tolist(), strict=True)) for row in values]

    def channels(
        self,
        face_type: str,
        allowed: frozenset[str] | None = None,
        tolerance: float = 0.012,
        base: Mapping[str, float] | None = None,
    ) -> dict[str, list[tuple[float, float]]]:
        """Per AU, keyframes (t_s, value) simplified to within ``tolerance`` of the sampled curve (with
        ``base``: crossfaded from and back to the face's own mouth, see :meth:`clip`)."""
        names, values = self.au_matrix(face_type, allowed)
        if base and any(abs(float(base.get(au, 0.0))) > 1e-9 for au in names):
            w = np.ones(len(self.times_s)) if self.presence is None else np.clip(self.presence, 0.0, 1.0)
            under = np.array([float(base.get(au, 0.0)) for au in names])
            values = w[:, None] * values + (1.0 - w[:, None]) * under[None, :]
        out: dict[str, list[tuple[float, float]]] = {}
        for j, au in enumerate(names):
            keep = _simplify(self.times_s, values[:, j], tolerance)
            out[au] = [(round(float(self.times_s[i]), 4), round(float(values[i, j]), 4)) for i in keep]
        return out

    def clip(
        self,
        face_type: str,
        allowed: frozenset[str] | None = None,
        name: str = "speech",
        base: Mapping[str, float] | None = None,
    ) -> ChannelClip:
        """A clip for the ``speech`` track: it provides the mouth AUs while it runs, nothing after. ``base``:
        the face's own mouth AUs under the speech (an expression's); the clip crossfades from them and
        back to them with :attr:`presence`, so the mouth does not jump when the speech takes or gives back
        the mouth (while it talks, the speech's shapes override them)."""
        channels = {
            au: tuple(Key(t, v) for t, v in keys) for au, keys in self.channels(face_type, allowed, base=base).items()
        }
        return ChannelClip(channels, self.duration_s, unlisted="hold", name=name, holds=False)


def _simplify(t: NDArray[np.float64], v: NDArray[np.float64], tol: float) -> list[int]:
    """Indices of a piecewise-linear fit within ``tol`` of every sample: the ends and the turning points,
    then, while some sample is further than ``tol`` from the fit, the worst sample of each such run."""
    n = len(t)
    if n <= 2:
        return list(range(n))
    d = np.diff(v)
    turning = np.nonzero(np.sign(d[1:]) != np.sign(d[:-1]))[0] + 1
    keep = np.unique(np.concatenate([[0, n - 1], turning]))
    for _ in range(64):
        err = np.abs(np.interp(t, t[keep], v[keep]) - v)
        bad = err > tol
        if not bad.any():
            break
        # the worst sample of each gap between kept points
        gap = np.searchsorted(keep, np.arange(n), side="right")
        order = np.lexsort((-err, gap))
        first = order[np.r_[True, np.diff(gap[order]) != 0]]
        add = first[bad[first]]
        keep = np.unique(np.concatenate([keep, add]))
    return [int(i) for i in keep]


def loudness_gain(
    samples: NDArray[np.float64] | None, rate_hz: int, times_audio_s: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Opening gain per sample time from the audio's RMS (20 ms windows): ~1 at typical loudness, down to
    0.45 for quiet syllables, up to 1.15 for loud ones."""
    if samples is None or len(samples) == 0:
        return np.ones_like(times_audio_s)
    win = max(int(0.02 * rate_hz), 1)
    centres = np.clip((times_audio_s * rate_hz).astype(int), 0, len(samples) - 1)
    sq = np.concatenate([[0.0], np.cumsum(samples.astype(np.float64) ** 2)])
    lo = np.clip(centres - win // 2, 0, len(samples))
    hi = np.clip(centres + win // 2 + 1, 0, len(samples))
    rms = np.sqrt((sq[hi] - sq[lo]) / np.maximum(hi - lo, 1))
    voiced = rms[rms > 0.02 * (rms.max() or 1.0)]
    ref = float(np.percentile(voiced, 80)) if len(voiced) else 1.0
    gain: NDArray[np.float64] = np.clip(0.45 + 0.6 * rms / max(ref, 1e-9), 0.45, 1.15)
    return gain


def plan_from_visemes(
    segments: Sequence[TimedViseme],
    *,
    audio_duration_s: float,
    samples: NDArray[np.float64] | None = None,
    sample_rate_hz: int = 16000,
    lead_s: float = DEFAULT_LEAD_S,
    close_s: float = DEFAULT_CLOSE_S,
    intensity: float = 1.0,
    rate_hz: float = PLAN_RATE_HZ,
) -> LipSyncPlan:
    """The lip-sync plan of timed visemes (audio clock) for audio of ``audio_duration_s``."""
    for name, value, lo, hi in (
        ("lead_s", lead_s, 0.0, 0.5),
        ("close_s", close_s, 0.02, 0.15),
        ("intensity", intensity, 0.0, 1.5),
        ("audio_duration_s", audio_duration_s, 0.0, 600.0),
    ):
        if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
            raise SpeechError(f"{name}: expected a number within {lo:g}..{hi:g}, got {value!r}")
    spoken = [s for s in segments if s.viseme != "sil"]
    end_mouth_s = lead_s + audio_duration_s + 0.05
    times = np.arange(0.0, end_mouth_s + 1e-9, 1.0 / rate_hz)
    audio_t = times  # the mouth at time t shows the sound at audio time t (the audio starts lead_s later)
    feats = np.zeros((len(times), len(FEATURES)))
    if spoken:
        centres = np.array([s.centre_s for s in segments])
        halves = np.maximum(np.array([s.duration_s for s in segments]) * 0.5, _MIN_HALF_S)
        alpha = np.array([VISEME_SHAPES[s.viseme].dominance for s in segments])
        shapes = np.array([[VISEME_SHAPES[s.viseme].shape[f] for f in FEATURES] for s in segments])
        dist = np.abs(audio_t[:, None] - centres[None, :]) / halves[None, :]
        dom = alpha[None, :] * np.exp(-_THETA * np.maximum(dist - 0.6, 0.0))
        feats = dom @ shapes / np.maximum(dom.sum(axis=1, keepdims=True), 1e-12)
        gain = loudness_gain(samples, sample_rate_hz, audio_t) * intensity
        for f in ("open", "part"):
            j = FEATURES.index(f)
            feats[:, j] *= gain
        _close_bilabials(feats, audio_t, segments)
        first = spoken[0].start_s
        last = spoken[-1].end_s
        # before the first and after the last spoken segment: neutral (ramped over close_s)
        ramp_in = np.clip((audio_t - (first - 0.12)) / 0.12, 0.0, 1.0)
        ramp_out = np.clip((last + close_s - audio_t) / close_s, 0.0, 1.0)
        presence = np.minimum(ramp_in, ramp_out)
        feats *= presence[:, None]
    else:
        presence = np.zeros(len(times))
    feats = np.clip(feats, 0.0, 1.0)
    return LipSyncPlan(times, feats, float(lead_s), float(audio_duration_s), tuple(segments), presence)


def _close_bilabials(feats: NDArray[np.float64], t: NDArray[np.float64], segments: Sequence[TimedViseme]) -> None:
    """Inside every PP segment: jaw and lip part to 0 and press on, blended in over 30 ms at the edges."""
    jo, jp, jr = FEATURES.index("open"), FEATURES.index("part"), FEATURES.index("press")
    for s in segments:
        if not VISEME_SHAPES[s.viseme].closes_lips:
            continue
        core_lo = s.start_s + 0.25 * s.duration_s
        core_hi = s.end_s - 0.25 * s.duration_s
        edge = 0.03
        w = np.clip(1.0 - np.maximum(core_lo - t, t - core_hi) / edge, 0.0, 1.0)  # 1 inside the core
        w = np.where((t >= core_lo) & (t <= core_hi), 1.0, w)
        for j in (jo, jp):
            feats[:, j] *= 1.0 - w
        feats[:, jr] = np.maximum(feats[:, jr], w * VISEME_SHAPES[s.viseme].shape["press"])


def plan_from_features(
    times_audio_s: NDArray[np.float64],
    features: Mapping[str, NDArray[np.float64]],
    *,
    audio_duration_s: float,
    lead_s: float = 0.0,
) -> LipSyncPlan:
    """A plan from feature tracks measured on the audio (the envelope path): shifted by ``lead_s``."""
    n = len(times_audio_s)
    feats = np.zeros((n, len(FEATURES)))
    for name, values in features.items():
        if name not in FEATURES:
            raise SpeechError(f"feature {name!r}: expected one of {FEATURES}")
        feats[:, FEATURES.index(name)] = np.clip(np.asarray(values, dtype=float), 0.0, 1.0)
    return LipSyncPlan(np.asarray(times_audio_s, dtype=float), feats, float(lead_s), float(audio_duration_s))
