"""A `Face` call takes its frames as they arrive: the service's trace queue stays a few frames long during
the call (it held every frame until the call ended: ~0.75 GB an hour at 50 Hz), and the call's statistics
still count every frame."""

from __future__ import annotations

import threading

from servoface.controller.face import Face


def test_a_call_drains_its_frames_as_they_arrive() -> None:
    face = Face.open("human", emulate=True, rate_hz=50.0)
    longest = [0]
    done = threading.Event()

    def watch() -> None:
        while not done.wait(0.02):
            for sub in face.service.observers._by_kind["trace"]:
                longest[0] = max(longest[0], len(sub))

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        perf = face.express("happiness", transition_s=0.5, hold_s=4.0)
    finally:
        done.set()
        watcher.join()
        face.close(ease_s=0.0)
    assert longest[0] <= 40, longest[0]  # ~5 frames between drains (0.1 s at 50 Hz), with scheduling slack
    frames = perf.stats.frames
    assert frames == perf.traces.total and frames >= 4.5 * 50 * 0.9  # every frame counted, none lost
    assert len(perf.traces) == frames  # (the ring keeps 3000: all of them here)
    assert perf.stats.elapsed_s > 4.0 and perf.stats.achieved_hz > 40
    assert [t.index for t in perf.traces] == list(range(perf.traces[0].index, perf.traces[0].index + frames))
    assert perf.traces[0].t_s >= -1e-9  # timed from the call's start
