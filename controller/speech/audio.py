"""WAV in and out (stdlib ``wave``; mono 16-bit PCM), resampling, and loudness.

A WAV file is read through :func:`servoface.calibration.boundedfile.read_bounded` and parsed from memory: a
directory, a device or a FIFO is refused before it is opened, a file over ``AUDIO_LIMIT_BYTES`` (512 MiB)
before a byte is read.
"""

from __future__ import annotations

import io
import os
import tempfile
import wave
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from servoface.calibration.boundedfile import AUDIO_LIMIT_BYTES, read_bounded
from servoface.controller.speech.errors import SpeechError

MAX_AUDIO_S = 600.0


def write_wav(path: str | Path, samples: NDArray[np.int16], rate_hz: int) -> Path:
    """Write mono 16-bit PCM atomically (a temp file renamed into place)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    os.close(fd)
    try:
        with wave.open(tmp, "wb") as w:
            w.setnchannels(1)
            w.setsampwidth(2)
            w.setframerate(int(rate_hz))
            w.writeframes(np.asarray(samples, dtype="<i2").tobytes())
        os.chmod(tmp, 0o644)  # as a file written in place (mkstemp makes it 0600)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out


def read_wav(path: str | Path) -> tuple[NDArray[np.float64], int]:
    """Mono float samples in -1..1 and the rate of a PCM WAV (8/16/24/32-bit; channels averaged).

    SpeechError names the path: a file that is not a PCM WAV, not a regular file, or over 512 MiB."""
    p = Path(path)
    try:
        blob = read_bounded(
            p, lambda reason: SpeechError(f"{p}: {reason}"), what="a WAV file", limit_bytes=AUDIO_LIMIT_BYTES
        )
        with wave.open(io.BytesIO(blob), "rb") as w:
            channels, width, rate, n = w.getnchannels(), w.getsampwidth(), w.getframerate(), w.getnframes()
            if rate <= 0 or n / max(rate, 1) > MAX_AUDIO_S:
                raise SpeechError(f"{p}: expected at most {MAX_AUDIO_S:g} s of audio at a positive rate")
            raw = w.readframes(n)
    except (OSError, EOFError, wave.Error) as err:
        raise SpeechError(f"{p}: cannot read as a PCM WAV file ({err})") from err
    if width == 1:
        data = (np.frombuffer(raw, np.uint8).astype(np.float64) - 128.0) / 128.0
    elif width == 2:
        data = np.frombuffer(raw, "<i2").astype(np.float64) / 32768.0
    elif width == 3:
        b = np.frombuffer(raw, np.uint8).reshape(-1, 3).astype(np.int32)
        v = b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16)
        v = np.where(v >= 1 << 23, v - (1 << 24), v)
        data = v.astype(np.float64) / float(1 << 23)
    elif width == 4:
        data = np.frombuffer(raw, "<i4").astype(np.float64) / float(1 << 31)
    else:
        raise SpeechError(f"{p}: sample width {width} bytes is not supported (expected 1-4)")
    if channels > 1:
        data = data[: len(data) // channels * channels].reshape(-1, channels).mean(axis=1)
    return data, rate


def resample(samples: NDArray[np.float64], rate_hz: int, to_hz: int) -> NDArray[np.float64]:
    """Polyphase resampling (scipy) to ``to_hz``."""
    if rate_hz == to_hz:
        return samples
    from math import gcd

    from scipy.signal import resample_poly

    g = gcd(int(rate_hz), int(to_hz))
    return np.asarray(resample_poly(samples, to_hz // g, rate_hz // g), dtype=np.float64)


def to_float(samples: NDArray[np.int16]) -> NDArray[np.float64]:
    return np.asarray(samples, dtype=np.float64) / 32768.0
