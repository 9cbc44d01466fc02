"""Speech: planning time and audio-to-goal skew on the emulated wire.

- **plan**: a ~10 s sentence, text -> espeak-ng synthesis -> visemes -> coarticulated plan -> AU keys for
  the speech track (median of 5), against 200 ms.
- **skew**: the sentence spoken on the emulated human head (1 Mbps, wire time on) through ``Face.say``'s
  path (``HeadService.speak``): for every frame, the time its jaw goal finished on the wire (decoded from
  the emulator's packet log) minus the time the audio clock plays the sound that frame shows (the sound
  starts after the lead plus the pipeline's measured frame time); p95 against 20 ms. The audio clock is
  the device's where a sound device plays, else the monotonic clock (this machine and CI: no device).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Iterator

import numpy as np
from servoface.controller.benchmarks.figure import Figure

SENTENCE = (
    "Good morning and welcome to the museum. My name is Ada, and I am a robot head built from twenty "
    "servos. Please come closer, look at my face, and tell me how you feel today."
)


def _plan_ms(text: str, repeats: int) -> tuple[float, float]:
    from servoface.controller.speech.lipsync import speech_from_text

    times, duration = [], 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        speech = speech_from_text(text)
        speech.plan.channels("human")
        times.append((time.perf_counter() - t0) * 1e3)
        duration = speech.duration_s
    return statistics.median(times), duration


def _skew_ms(text: str) -> tuple[list[float], int, str]:
    from servoface.controller.face import Face
    from servoface.controller.speech.lipsync import speech_from_text
    from servoface.controller.speech.say import say_on_face

    speech = speech_from_text(text)
    with Face.open("human", emulate=True) as face:
        face.hold(0.2)
        jaw = face.head.servo_ids["jaw"]
        chain = face.chain
        offset = time.monotonic() - chain._clock()  # noqa: SLF001 - emulator clock -> monotonic
        n_before = len([w for w in chain.goal_writes() if w[1] == jaw])
        run = say_on_face(face, speech, audio_out=False)
        writes = [w for w in chain.goal_writes() if w[1] == jaw][n_before:]
    traces = list(run.performance.traces)
    # the frames before the speech track started (scheduled START_AHEAD_S ahead) are on the wire too: align
    # the frames' jaw goals with the writes' (the shift where the most of the first 100 agree)
    goals = [t.goals_sent[jaw] for t in traces[:100]]
    shift = max(
        range(min(40, len(writes))), key=lambda k: sum(g == w[2] for g, w in zip(goals, writes[k:], strict=False))
    )
    writes = writes[shift:]
    skews = []
    for trace, (t_wire, _, goal) in zip(traces, writes, strict=False):
        if goal != trace.goals_sent[jaw]:  # frames and writes out of step: stop matching
            break
        # the frame shows the mouth for service-local time t (the speech track's t0 = its start), whose
        # sound the audio clock plays at start + latency + t (the monotonic clock; a device would shift it)
        due = run.start_monotonic_s + run.latency_s + trace.t_s
        skews.append((t_wire + offset - due) * 1e3)
    return skews, len(traces), run.clock


def run(quick: bool = False) -> Iterator[Figure]:
    text = SENTENCE if not quick else SENTENCE.split(".")[0] + "."
    plan_ms, duration_s = _plan_ms(text, 2 if quick else 5)
    yield Figure(
        f"plan a {duration_s:.1f} s sentence (synthesis + visemes + plan + keys)",
        plan_ms,
        "ms",
        goal=200.0,
        better="lower",
        note="median; espeak-ng synthesis included",
    )
    skews, frames, clock = _skew_ms(text)
    p95 = float(np.percentile(np.abs(skews), 95)) if skews else float("nan")
    yield Figure(
        "audio-to-goal skew on the emulated wire, p95 of |skew|",
        p95,
        "ms",
        goal=20.0,
        better="lower",
        note=f"{len(skews)} of {frames} frames matched; signed median {statistics.median(skews):.1f} ms "
        f"(+ = goal after the sound), range {min(skews):.1f}..{max(skews):.1f} ms; human head, 1 Mbps, "
        f"wire time on, 50 Hz; the mouth followed the {clock} clock (no sound device: the WAV's schedule)",
    )
