"""Issue 17's controller fast paths give exactly what the straightforward path gives (seeded random inputs).

- `StrainedHealth` reuses a servo's record when the snapshot holds the very state object of the last frame
  (and the limit is the same): compared with the strained part of `gate_health` while states are kept,
  replaced by equal copies, changed, and while the limits change under kept states.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np
import pytest
from servoface.controller.face import Face
from servoface.controller.telemetry import StrainedHealth, gate_health
from servoface.hardware.snapshot import ChainSnapshot

from tests.controller.pipeline_pairs import face_pair
from tests.controller.test_pipeline_health import FAULTS


@pytest.fixture
def faces() -> Iterator[tuple[Face, Face]]:
    with face_pair() as pair:
        yield pair


def _step_telemetry(snap: ChainSnapshot, limits: dict[int, float], rng: np.random.Generator) -> ChainSnapshot:
    """Per servo: the same state object (most), an equal copy, or changed slow fields."""
    servos = dict(snap.servos)
    for sid, state in list(servos.items()):
        r = rng.random()
        if r < 0.6:
            continue
        if r < 0.75:
            servos[sid] = dataclasses.replace(state)  # equal, not the same object
            continue
        limit = limits.get(sid, 70.0)
        servos[sid] = dataclasses.replace(
            state,
            temperature_c=None if rng.random() < 0.05 else int(limit - rng.choice([1, 3, 8, 20, 30])),
            load_fraction=None if rng.random() < 0.05 else float(rng.choice([-1, 1]) * rng.random() ** 0.3),
            faults=FAULTS[int(rng.integers(len(FAULTS)))],
            derated=bool(rng.random() < 0.1),
        )
    return dataclasses.replace(snap, servos=servos)


def test_strained_health_with_kept_states_and_changing_limits_is_the_plain_one(faces: tuple[Face, Face]) -> None:
    face, _ = faces
    p = face.pipeline
    policy = p.gate.config.health
    snap = face.pipeline.hold()
    assert snap is not None
    strained = StrainedHealth(p._ids)
    base = dict(p.temperature_limits_c)
    limits = dict(base)
    rng = np.random.default_rng(17)
    kept_frames = limit_moves = nonempty = 0
    for _ in range(400):
        before = dict(snap.servos)
        snap = _step_telemetry(snap, base, rng)
        kept_frames += any(snap.servos[s] is before[s] for s in before)
        if rng.random() < 0.2:  # a limit moves while the servo's state object stays the same
            sid = int(rng.choice(sorted(limits)))
            limits[sid] = base[sid] + float(rng.choice([-25.0, -10.0, 0.0, 5.0]))
            limit_moves += 1
        full = gate_health(snap, limits, p._ids)
        expected = {sid: h for sid, h in full.items() if h.strained(policy.hot_margin_c, policy.load_limit)}
        assert strained(snap, limits, policy) == expected
        nonempty += bool(expected)
    assert kept_frames > 300 and limit_moves > 40 and nonempty > 200
