"""The service's observers, turned into studio messages: one thread reads the bounded subscriptions
(frames at 20 Hz, telemetry at 10 Hz, every fault and command status change) and hands JSON-ready dicts to
:meth:`Studio.emit`; the state goes out at 2 Hz and on every change. The subscriptions drop their oldest
item when full, so a slow browser never reaches the loop."""

from __future__ import annotations

import threading
import time

from servoface.controller.studio import views
from servoface.controller.studio.studio import Studio

FRAME_HZ = 20.0
TELEMETRY_HZ = 10.0
STATE_HZ = 2.0


class Pump:
    def __init__(self, studio: Studio) -> None:
        self.studio = studio
        svc = studio.service
        self._traces = svc.subscribe("trace", rate_hz=FRAME_HZ, maxlen=8)
        self._telemetry = svc.subscribe("telemetry", rate_hz=TELEMETRY_HZ, maxlen=8)
        self._faults = svc.subscribe("fault", maxlen=256)
        self._playback = svc.subscribe("playback", maxlen=256)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="studio-pump", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        studio = self.studio
        next_state = 0.0
        while not self._stop.is_set():
            first = self._traces.get(timeout_s=0.05)  # wakes on a frame (or after 50 ms)
            busy = False
            traces = ([first] if first is not None else []) + self._traces.drain()
            if traces:
                studio.emit(views.frame(traces[-1]))
            snaps = self._telemetry.drain()
            if snaps:
                studio.emit({"type": "telemetry", **views.telemetry(snaps[-1], studio.roles)})
            for event in self._faults.drain():
                studio.emit(views.fault(event))
                busy = True
            if self._playback.drain():
                busy = True
            now = time.monotonic()
            if busy or now >= next_state:
                next_state = now + 1.0 / STATE_HZ
                studio.push_state()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        for sub in (self._traces, self._telemetry, self._faults, self._playback):
            sub.close()
