"""TSS on the built-in dog head: ears against the skull, tongue against the jaw, jaw against the teeth."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.gate.collision import PartCollisions, auto_pairs
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.tss_build import TssParams, default_cache_dir, summed_reduction


@pytest.fixture(scope="module")
def dog_collisions() -> PartCollisions:
    from servoface.sim.heads import load_head

    head = load_head("dog")
    tree = JointTree(head.joints)
    return PartCollisions(head, tree, auto_pairs(head, tree), TssParams(), default_cache_dir())


def test_dog_pairs_of_the_brief_are_checked(dog_collisions: PartCollisions) -> None:
    names = {frozenset((s.a, s.b)) for s in dog_collisions.pairs_active}
    for pair in (("skull", "ear_l"), ("skull", "ear_r"), ("jaw", "tongue_tip"), ("jaw", "teeth_upper")):
        assert frozenset(pair) in names


@pytest.mark.parametrize("batched", [False, True])
def test_dog_broad_phase_misses_no_exact_collision(dog_collisions: PartCollisions, batched: bool) -> None:
    col = dog_collisions
    tree = col.tree
    rng = np.random.default_rng(21 if batched else 22)
    q = rng.uniform(tree.lower_deg, tree.upper_deg, size=(250, len(tree.names)))
    world = tree.world(q)
    flags = (
        col.broad.flag(world, q) if batched else np.array([col.broad.flag(w, a) for w, a in zip(world, q, strict=True)])
    )
    found = 0
    for k in range(len(q)):
        for p, spec in enumerate(col.specs):
            if flags[k, p] or col._collide(spec, world[k]):
                hit = col._collide(spec, world[k])
                assert flags[k, p] or not hit, f"missed {spec.a}/{spec.b} at {q[k].round(1).tolist()}"
                found += int(hit)
    assert found >= 10, "the sweep found too few collisions to mean anything"
    assert summed_reduction([b.table for b in col.built]) >= 0.95
