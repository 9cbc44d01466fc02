"""Joint-only skin proven inside the strain limits (`skin_proof`) is left out of the per-frame measure: on
random poses it never breaks the limits, and the gate gives the same verdicts, goals, step fractions and
findings with the proof as without it (the straightforward path), on the dog (skin between skull and jaw,
driven by two servos: no per-tick table) — with the default limits and with limits so tight that part of
that skin is not proven and the strain checks fire."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate
from servoface.sim.gate.skin_proof import proven_static
from servoface.sim.gate.strain import StrainLimits

TIGHT = StrainLimits(max_stretch=1.3, min_compression=0.8, max_flipped=0)


def _gate(limits: StrainLimits, proofs: bool) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head("dog")
    assert head.calibration_path is not None
    cfg = GateConfig(strain=limits, skin_proofs=proofs)
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, cfg)


@pytest.fixture(scope="module")
def dog() -> TwinGate:
    return _gate(StrainLimits(), True)


@pytest.mark.parametrize("limits", [StrainLimits(), TIGHT], ids=["default", "tight"])
def test_proven_skin_stays_inside_the_limits_on_random_poses(dog: TwinGate, limits: StrainLimits) -> None:
    skin, tree = dog.skin, dog.tree
    proof = proven_static(skin, tree, limits)
    assert proof is not None
    edges, faces = proof
    assert edges.sum() > 1000 and faces.sum() > 1000, "nothing proven: the test would mean little"
    rng = np.random.default_rng(7)
    q = rng.uniform(tree.lower_deg, tree.upper_deg, size=(600, len(tree.names)))
    corners = np.array(np.meshgrid(*[[lo, hi] for lo, hi in zip(tree.lower_deg, tree.upper_deg, strict=True)]))
    q = np.vstack([q, corners.reshape(len(tree.names), -1).T[:64]])  # some corners of the box too
    world = tree.world(q)
    for start in range(0, len(q), 64):
        hi2, lo2, flips = skin.measure_static(world[start : start + 64], edges, faces)
        assert np.all(np.sqrt(hi2) <= limits.max_stretch), np.sqrt(hi2).max()
        assert np.all(np.sqrt(lo2) >= limits.min_compression), np.sqrt(lo2).min()
        assert np.all(flips == 0)
    if limits is TIGHT:  # part of the joint-only skin can break these: the proof must have kept it
        mv = skin.movable[skin._v]
        static_e = ~mv[skin._edges].any(axis=1)
        assert (static_e & ~edges).sum() > 0


@pytest.mark.parametrize("limits", [StrainLimits(), TIGHT], ids=["default", "tight"])
@pytest.mark.parametrize("scale", [0.25, 3.0])
def test_gate_gives_the_same_verdicts_with_the_proof(limits: StrainLimits, scale: float) -> None:
    new, old = _gate(limits, True), _gate(limits, False)
    assert new.skin_proven[0] > 0 and old.skin_proven == (0, 0)
    t = new.table
    rng = np.random.default_rng(int(scale * 10) + (7 if limits is TIGHT else 0))
    last = new.neutral_goals()
    kinds, checks = set(), set()
    for _ in range(70):
        base = np.array([last[i] for i in t.ids])
        req = np.clip(base + rng.uniform(-1, 1, t.n) * t.max_step_tick * scale, t.min_tick, t.max_tick)
        goals = {int(i): int(v) for i, v in zip(t.ids, req.astype(np.int64), strict=True)}
        a = new.check(goals, last)
        b = old.check(goals, last)
        assert (a.kind, a.goals_tick, a.step_fraction) == (b.kind, b.goals_tick, b.step_fraction)
        assert [(f.check, f.message, f.value) for f in a.findings] == [
            (f.check, f.message, f.value) for f in b.findings
        ]
        kinds.add(a.kind)
        checks |= {f.check for f in a.findings}
        last = a.goals_tick
    assert ("accept" if scale < 1 else "clip") in kinds, kinds
    if limits is TIGHT:
        assert "strain" in checks, checks
