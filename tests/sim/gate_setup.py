"""Shared set-up for the gate tests that compare a gate's fast path with the straightforward one: a
built-in head's gate from its shipped calibration, the pair with and without the lookup tables, and random
poses (a little beyond the joint limits too). Plain functions: each test file keeps its own fixtures."""

from __future__ import annotations

import numpy as np
from servoface.sim.gate import GateConfig, TwinGate


def builtin_gate(name: str, frame_period_s: float, config: GateConfig | None = None) -> TwinGate:
    """The built-in head ``name``'s gate, with the head's shipped calibration."""
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(name)
    assert head.calibration_path is not None
    return TwinGate(head, load_calibration(head.calibration_path), frame_period_s, config)


def table_pair(name: str) -> tuple[TwinGate, TwinGate]:
    """(with its clearance and axial tables, without: the straightforward path) for head ``name``, 60 Hz."""
    with_tables = builtin_gate(name, 1 / 60, GateConfig(clearance=True))
    return with_tables, builtin_gate(name, 1 / 60, GateConfig(clearance=False))


def random_poses(gate: TwinGate, n: int, seed: int) -> np.ndarray:
    """(n, J) joint angles, uniform over each joint's range widened by 5 % on both sides."""
    tree = gate.tree
    rng = np.random.default_rng(seed)
    span = tree.upper_deg - tree.lower_deg
    return rng.uniform(tree.lower_deg - 0.05 * span, tree.upper_deg + 0.05 * span, size=(n, len(tree.names)))
