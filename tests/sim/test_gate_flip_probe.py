"""`strain.probe_dots` (the clip search's flip probe) computes, for the triangles it probes, the numbers
`SkinTwin.measure_one` computes: on random poses of both heads (inside and a little beyond the limits) the
probe of every measured triangle counts the flips `measure_one` counts, and a probe of a random subset gives
bit for bit that subset's numbers; a probe made for another measured subset is refused."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.strain import flip_probe, probe_dots


@pytest.fixture(scope="module", params=["human", "dog"])
def gate(request: pytest.FixtureRequest) -> TwinGate:
    from servoface.calibration.fileformat import load_calibration
    from servoface.sim.heads import load_head

    head = load_head(request.param)
    return TwinGate(head, load_calibration(head.calibration_path), 1 / 60, GateConfig())


def test_probe_counts_what_measure_one_counts(gate: TwinGate) -> None:
    t = gate.table
    skin = gate.skin
    rng = np.random.default_rng(31)
    everything = flip_probe(skin, np.arange(skin.n_measured_faces))
    span = t.max_tick - t.min_tick
    flipped_poses = 0
    for trial in range(200):
        if trial % 2:
            goal = rng.integers(t.min_tick - span // 20, t.max_tick + span // 20 + 1)
        else:
            goal = np.clip(t.neutral_tick + rng.uniform(-1, 1, t.n) * span * 0.3, t.min_tick, t.max_tick)
        goal = goal.astype(np.int64)
        _, _, world, pulls = gate._pose_arrays(goal[None, :])
        offsets = gate.skin_source.offsets_rows(pulls[0], skin.fast_vertices)
        static = gate._static(goal)
        _, _, flips = skin.measure_one(world[0], offsets, static)
        dots = probe_dots(skin, world[0], offsets, everything)
        assert int(np.count_nonzero(dots <= 0.0)) + skin.const_flips + static[2] == flips
        flipped_poses += flips > 0
        pick = np.sort(rng.choice(skin.n_measured_faces, size=int(rng.integers(1, 40)), replace=False))
        sub = probe_dots(skin, world[0], offsets, flip_probe(skin, pick))
        assert np.array_equal(sub.view(np.uint32), dots[pick].view(np.uint32))
    assert flipped_poses >= 5  # the poses flip triangles: the counts are not all zero


def test_probe_of_another_subset_is_refused(gate: TwinGate) -> None:
    probe = flip_probe(gate.skin, np.arange(3))
    stale = type(probe)(probe.subset - 1, probe.faces, probe.verts, probe.corners, probe.normals)
    _, _, world, pulls = gate._pose_arrays(gate.table.neutral_tick[None, :])
    offsets = gate.skin_source.offsets_rows(pulls[0], gate.skin.fast_vertices)
    with pytest.raises(GateConfigError):
        probe_dots(gate.skin, world[0], offsets, stale)
