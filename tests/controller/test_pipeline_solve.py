"""`Pipeline._solve`'s array path (targets-only muscle model, clamps and goals as arrays) gives exactly what
the straightforward chain gives: `FaceModel.solve`'s targets, clamped one by one with one reason each,
through `HeadCalibration.targets_to_goals`, on random frames that clamp and on both built-in heads."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.face import Face
from servoface.controller.pipeline import Pipeline


def _reference(p: Pipeline, aus: dict[str, float]) -> tuple[object, ...]:
    targets = dict(p.face.solve(aus).actuator_targets)
    values = np.array([float(targets.get(s.role, n)) for s, n in zip(p._servos, p._neutral, strict=True)])
    clamped = np.clip(values, p._lo, p._hi)
    reasons = [
        f"[target] {s.role}: {v:.2f} {s.unit} outside the calibrated {lo:.2f}..{hi:.2f}, clamped"
        for s, v, lo, hi, c in zip(p._servos, values, p._lo, p._hi, clamped, strict=True)
        if abs(v - c) > 1e-6 * max(1.0, hi - lo)
    ]
    clamped_d = {s.role: float(c) for s, c in zip(p._servos, clamped, strict=True)}
    return targets, clamped_d, tuple(reasons), p.calibration.targets_to_goals(clamped_d)


@pytest.mark.parametrize("head_name", ["human", "dog"])
def test_solve_equals_the_straightforward_chain_on_random_frames(head_name: str) -> None:
    p = Face.offline(head_name).pipeline
    span = p._hi - p._lo  # the clamp range narrowed to its middle third, so that frames clamp
    p._lo, p._hi = p._lo + span / 3, p._hi - span / 3
    p._set_columns()
    names = sorted(p.face.au_names)
    rng = np.random.default_rng(12)
    clamps: set[int] = set()
    for _ in range(250):
        aus = {}
        for name in rng.choice(names, size=int(rng.integers(0, 9)), replace=False):
            lo, hi = p.face.au_range(str(name))
            aus[str(name)] = float(rng.choice([lo, hi])) if rng.random() < 0.3 else float(rng.uniform(lo, hi))
        p._solved = None
        got = p._solve(aus, {})
        want = _reference(p, aus)
        assert got == want
        assert [list(d) for d in got if isinstance(d, dict)] == [list(d) for d in want if isinstance(d, dict)]
        clamps.add(len(got[2]))  # type: ignore[arg-type]
    assert len(clamps) > 3  # frames with few and with many clamps


def test_column_goals_is_targets_to_goals() -> None:
    cal = Face.offline("human").pipeline.calibration
    rng = np.random.default_rng(13)
    roles = list(cal.roles)
    for _ in range(300):
        some = [roles[i] for i in rng.choice(len(roles), size=int(rng.integers(1, len(roles) + 1)), replace=False)]
        targets = {r: float(rng.uniform(cal[r].min_target, cal[r].max_target)) for r in some}
        want = cal.targets_to_goals(targets)
        got = cal.column_goals(cal.columns(some), np.array(list(targets.values())))
        assert dict(zip([cal.id_of(r) for r in some], got.tolist(), strict=True)) == want
