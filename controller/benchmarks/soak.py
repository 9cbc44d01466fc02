"""`servoface bench soak [--minutes N]`: a long run of a looping script on the human head, measuring memory
growth and loop-rate drift — the figures a head that runs all day at an exhibition depends on.

servoface drives the head over a pty, the emulated chain runs in its own process (``servoface emulate --head
human``, wire time on), so the resident set measured is servoface's alone, as with real servos. The shipped
human performance is played again and again (each `Face.play` a full performance with settling). RSS
(``/proc/self/statm``) is sampled after every performance; the first 90 s are warm-up (tables, caches, the
bounded trace rings filling: 3000 frames = 60 s at 50 Hz). Figures: RSS growth per hour (least-squares slope over the
samples after warm-up) against a ceiling of 20 MB/h (10 MB in a 30-minute soak), the growth over the run, and
the loop rate of the last performances against the first ones (drift, Hz).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator

from servoface.controller.benchmarks.figure import Figure

DEFAULT_MINUTES = 1.0
QUICK_MINUTES = 0.4
RSS_GOAL_MB_PER_H = 20.0


def rss_mb() -> float:
    """Resident set size of this process in MB (Linux ``/proc/self/statm``)."""
    with open("/proc/self/statm") as fh:
        resident_pages = int(fh.read().split()[1])
    return resident_pages * os.sysconf("SC_PAGE_SIZE") / 1e6


def slope_per_h(samples: list[tuple[float, float]]) -> float:
    """Least-squares slope of (t_s, value) in value per hour (0 with fewer than two samples)."""
    if len(samples) < 2:
        return 0.0
    n = len(samples)
    mt = sum(t for t, _ in samples) / n
    mv = sum(v for _, v in samples) / n
    den = sum((t - mt) ** 2 for t, _ in samples)
    if den == 0:
        return 0.0
    return sum((t - mt) * (v - mv) for t, v in samples) / den * 3600.0


def run(quick: bool = False, minutes: float | None = None) -> Iterator[Figure]:
    from servoface.controller.face import Face

    total_s = 60.0 * (minutes if minutes is not None else QUICK_MINUTES if quick else DEFAULT_MINUTES)
    with tempfile.TemporaryDirectory(prefix="servoface-soak-") as tmp:
        emulator = subprocess.Popen(
            [sys.executable, "-m", "servoface.controller.cli", "emulate", "--head", "human"],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env={**os.environ, "SERVOFACE_LOCK_DIR": tmp},
        )
        old_lock_dir = os.environ.get("SERVOFACE_LOCK_DIR")
        os.environ["SERVOFACE_LOCK_DIR"] = tmp
        try:
            assert emulator.stdout is not None
            port = emulator.stdout.readline().strip()
            samples: list[tuple[float, float]] = []
            rates: list[float] = []
            with Face.open("human", port=port) as face:
                warm_up_s = min(total_s / 2, 1.5 * (face.traces.maxlen or 0) / face.pipeline.rate_hz)
                t0 = time.monotonic()
                start_rss = None
                while time.monotonic() - t0 < total_s:
                    perf = face.play("human_performance")
                    rates.append(float(perf.summary().get("loop", {}).get("achieved_hz") or 0.0))
                    now = time.monotonic() - t0
                    if start_rss is None:
                        if now < warm_up_s:
                            continue
                        start_rss = rss_mb()  # warmed up: the trace rings are full
                        samples.append((now, start_rss))
                        continue
                    samples.append((now, rss_mb()))
                    if perf.interrupted:
                        break
        finally:
            if old_lock_dir is None:
                os.environ.pop("SERVOFACE_LOCK_DIR", None)
            else:
                os.environ["SERVOFACE_LOCK_DIR"] = old_lock_dir
            emulator.send_signal(signal.SIGTERM)
            try:
                emulator.wait(timeout=10)
            except subprocess.TimeoutExpired:
                emulator.kill()
    elapsed_min = total_s / 60.0
    growth = (samples[-1][1] - (start_rss or samples[0][1])) if samples else 0.0
    per_h = slope_per_h(samples)
    n = max(1, len(rates) // 4)
    first = sum(rates[:n]) / n if rates else 0.0
    last = sum(rates[-n:]) / n if rates else 0.0
    yield Figure(
        "soak: RSS growth per hour (after warm-up)",
        per_h,
        "MB/h",
        goal=RSS_GOAL_MB_PER_H,
        better="lower",
        note=f"{len(samples)} samples over {elapsed_min:.1f} min; RSS {samples[-1][1] if samples else 0:.0f} MB",
    )
    yield Figure(
        f"soak: RSS growth over {elapsed_min:.0f} min",
        growth,
        "MB",
        goal=RSS_GOAL_MB_PER_H * elapsed_min / 60.0 if elapsed_min >= 10 else None,
        better="lower",
        note=f"from {start_rss or 0:.0f} MB after the first performance",
    )
    yield Figure(
        "soak: loop rate, last quarter vs first",
        last,
        "Hz",
        limit=first if first > 0 else None,
        note=f"{len(rates)} performances; drift {last - first:+.2f} Hz (first quarter {first:.2f} Hz)",
    )
