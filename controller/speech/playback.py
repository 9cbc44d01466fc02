"""Sound output for a talking head: the audio device's clock when there is one, else none.

``sounddevice`` (PortAudio) is optional: ``pip install sounddevice`` and a sound card. When it is missing or
there is no output device, speech still plays on the head, timed by the service clock, and the audio is
only written to its WAV file.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass
class AudioOut:
    """Plays one buffer, started at a monotonic time; ``available`` False means no device (silent)."""

    available: bool
    reason: str = ""
    _thread: threading.Thread | None = None

    def play_at(self, samples: NDArray[np.float64], rate_hz: int, start_monotonic_s: float) -> None:
        """Start ``samples`` at ``start_monotonic_s`` (time.monotonic) on the default output, non-blocking."""
        if not self.available:
            return

        def run() -> None:
            import sounddevice  # type: ignore[import-not-found]

            delay = start_monotonic_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            sounddevice.play(np.asarray(samples, dtype=np.float32), rate_hz, blocking=True)

        self._thread = threading.Thread(target=run, name="servoface-audio", daemon=True)
        self._thread.start()

    def wait(self, timeout_s: float = 60.0) -> None:
        if self._thread is not None:
            self._thread.join(timeout_s)


def open_audio_out() -> AudioOut:
    """An output on the default sound device, or a silent one saying why not."""
    try:
        import sounddevice
    except (ImportError, OSError) as err:
        return AudioOut(False, f"no sound output (sounddevice/PortAudio not available: {err})")
    try:
        device = sounddevice.query_devices(kind="output")
    except Exception as err:  # PortAudio raises its own error type when there is no device  # noqa: BLE001
        return AudioOut(False, f"no sound output device ({err})")
    return AudioOut(True, f"sound on {device.get('name', 'default output')}")
