"""Shared set-up for the tests that compare an optimised pipeline path with the straightforward one: two
emulated human heads stepped side by side, random AU frames to step them with, and random telemetry."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
from servoface.controller.face import Face
from servoface.controller.pipeline import Pipeline
from servoface.hardware.snapshot import FaultKind, ServoState

FAULTS = [frozenset(), frozenset({FaultKind.OVERLOAD}), frozenset({FaultKind.THERMAL_DERATE}),
          frozenset({FaultKind.VOLTAGE_LOW})]  # fmt: skip


def au_names(pipeline: Pipeline) -> list[str]:
    """The head's unsided AU names, sorted (the frames' vocabulary)."""
    return sorted(a for a in pipeline.face.au_names if a[-1] not in "LR")


def random_frames(
    names: list[str], n: int, seed: int, *, jump: float = 0.15, move: float = 0.85, sigma: float = 0.15
) -> list[dict[str, float]]:
    """Random AU frames: with probability ``jump`` four AUs jump to random levels (clips), up to ``move`` one
    AU moves by N(0, ``sigma``), else the frame repeats the last one exactly (a held command)."""
    rng = np.random.default_rng(seed)
    current = {a: 0.0 for a in names}
    out = []
    for _ in range(n):
        kind = rng.random()
        if kind < jump:
            for a in rng.choice(names, size=4, replace=False):
                current[str(a)] = float(rng.random())
        elif kind < move:
            a = str(rng.choice(names))
            current[a] = float(np.clip(current[a] + rng.normal(0.0, sigma), 0.0, 1.0))
        out.append({a: round(v, 4) for a, v in current.items() if v > 0})
    return out


@contextmanager
def face_pair() -> Iterator[tuple[Face, Face]]:
    """Two emulated human heads (no wire time), per-time caps off: stepped back to back, per-time caps
    would make the verdicts depend on timing."""
    a = Face.open("human", emulate=True, wire_time=False)
    b = Face.open("human", emulate=True, wire_time=False)
    try:
        for face in (a, b):
            face.pipeline.per_time_caps = False
        yield a, b
    finally:
        a.close(ease_s=0.0)
        b.close(ease_s=0.0)


def changed_state(state: ServoState, limit_c: float, rng: np.random.Generator) -> ServoState:
    """``state`` with new slow fields: temperature near or under ``limit_c``, load anywhere (each None now and
    then), a fault or none (`FAULTS`), derated or not."""
    return dataclasses.replace(
        state,
        temperature_c=None if rng.random() < 0.05 else int(limit_c - rng.choice([1, 3, 8, 20, 30])),
        load_fraction=None if rng.random() < 0.05 else float(rng.choice([-1, 1]) * rng.random() ** 0.3),
        faults=FAULTS[int(rng.integers(len(FAULTS)))],
        derated=bool(rng.random() < 0.1),
    )
