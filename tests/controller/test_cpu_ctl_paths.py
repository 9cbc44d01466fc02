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

from tests.controller.pipeline_pairs import changed_state, face_pair


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
        servos[sid] = changed_state(state, limits.get(sid, 70.0), rng)
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


def _clamp_plain(p: object, targets: dict[str, float]) -> tuple[np.ndarray, list[str]]:
    """`Pipeline._clamp_array` the straightforward way (np.clip, reasons always built)."""
    servos, lo, hi = p._servos, p._lo, p._hi  # type: ignore[attr-defined]
    values = np.array([float(targets.get(s.role, n)) for s, n in zip(servos, p._neutral, strict=True)])  # type: ignore[attr-defined]
    clamped = np.clip(values, lo, hi)
    off = np.abs(values - clamped) > p._clamp_tol  # type: ignore[attr-defined]
    reasons = [
        f"[target] {servos[i].role}: {values[i]:.2f} {servos[i].unit} outside the calibrated {lo[i]:.2f}.."
        f"{hi[i]:.2f}, clamped"
        for i in np.flatnonzero(off).tolist()
    ]
    return clamped, reasons


def test_clamping_targets_is_np_clip_with_the_same_reasons(faces: tuple[Face, Face]) -> None:
    face, _ = faces
    p = face.pipeline
    rng = np.random.default_rng(5)
    clipped = clean = 0
    for _ in range(400):
        targets: dict[str, float] = {}
        inside = rng.random() < 0.3  # a frame whose targets all lie in range (the common case)
        for s, lo, hi in zip(p._servos, p._lo, p._hi, strict=True):
            r = rng.random()
            if r < 0.1:
                continue  # missing: the neutral
            span = hi - lo
            if r < 0.7 or inside:
                targets[s.role] = float(rng.uniform(lo, hi))
            elif r < 0.8:
                targets[s.role] = float(
                    rng.choice([lo, hi]) + rng.choice([-1, 1]) * rng.choice([0.0, 1e-9, 1e-3]) * span
                )
            else:
                targets[s.role] = float(rng.uniform(lo - span, hi + span))
        got, reasons = p._clamp_array(targets)
        want, want_reasons = _clamp_plain(p, targets)
        assert got.tobytes() == want.tobytes() and reasons == want_reasons
        clipped += bool(reasons)
        clean += not reasons
    with pytest.raises(Exception, match="non-finite"):
        p._clamp_array({p._servos[0].role: float("nan")})
    assert clipped > 100 and clean > 20
