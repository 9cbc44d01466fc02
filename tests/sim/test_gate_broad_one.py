"""`TssBroadPhase.balls_meet` for one pose (identity appended as is, |d| as sqrt of the sum of squares)
gives what the straightforward code gives (a broadcast identity and ``np.linalg.norm``) and what the batch
gives row by row, on seeded random poses of both built-in heads inside and a little beyond the joint limits
(where the clearance tables answer differently), with and without angles."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.gate import TwinGate
from servoface.sim.gate.tss_runtime import TssBroadPhase


def _gate(name: str) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(name)
    assert head.calibration_path is not None
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 50)


def _plain_balls_meet(b: TssBroadPhase, world: np.ndarray, angles: np.ndarray | None) -> np.ndarray:
    """The code before the one-pose branch."""
    lead = world.shape[:-3]
    out = np.zeros((*lead, b.n_pairs), dtype=bool)
    if not len(b._always_idx):
        return out
    eye = np.broadcast_to(np.eye(4), (*lead, 1, 4, 4))
    full = np.concatenate([world, eye], axis=-3)
    ca = np.einsum("...bij,bj->...bi", full[..., b._ball_slot_a, :3, :], b._ball_a)
    cb = np.einsum("...bij,bj->...bi", full[..., b._ball_slot_b, :3, :], b._ball_b)
    meet = np.linalg.norm(ca - cb, axis=-1) <= b._ball_reach
    cl = b.clearance
    if cl is not None and angles is not None and b._cl_pairs:
        if lead:
            meet[..., b._cl_rows] &= ~cl.clear(angles)[..., b._cl_tables]
        elif meet[b._cl_rows].any():
            q = angles.tolist()
            for r, t in b._cl_pairs:
                if meet[r] and cl.clear_one(t, q):
                    meet[r] = False
    out[..., b._always_idx] = meet
    return out


@pytest.mark.parametrize("name", ["human", "dog"])
def test_one_pose_balls_meet_equals_the_plain_code_and_the_batch(name: str) -> None:
    gate = _gate(name)
    b, tree = gate.collisions.broad, gate.tree
    rng = np.random.default_rng(31)
    span = tree.upper_deg - tree.lower_deg
    q = rng.uniform(tree.lower_deg - 0.1 * span, tree.upper_deg + 0.1 * span, size=(400, len(tree.names)))
    stop = rng.random(q.shape) < 0.3  # some joints at a stop, where parts come closest
    q = np.where(stop, np.where(rng.random(q.shape) < 0.5, tree.lower_deg, tree.upper_deg), q)
    world = tree.world(q)
    batch = b.balls_meet(world, q)
    assert np.array_equal(batch, _plain_balls_meet(b, world, q))
    met = 0
    for k in range(len(q)):
        one = tree.world_one(q[k])
        got = b.balls_meet(one, q[k])
        assert got.dtype == np.bool_ and got.shape == (b.n_pairs,)
        assert np.array_equal(got, _plain_balls_meet(b, one, q[k])), k
        assert np.array_equal(got, batch[k]), k
        assert np.array_equal(b.balls_meet(one), _plain_balls_meet(b, one, None)), k
        assert np.array_equal(b.flag(one, q[k]), b.flag(one[None], q[k][None])[0]), k
        met += int(got.any())
    assert met > 0  # the test sees pairs whose balls meet
