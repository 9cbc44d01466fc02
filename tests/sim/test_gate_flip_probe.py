"""`strain.probe_dots` (the clip search's flip probe) computes, for the triangles it probes, the numbers
`SkinTwin.measure_one` computes: on random poses of both heads (inside and a little beyond the limits) the
probe of every measured triangle counts the flips `measure_one` counts, and a probe of a random subset gives
bit for bit that subset's numbers, and both equal bit for bit a per-coordinate copy of `measure_one`'s
face arithmetic (kept here); a probe made for another measured subset is refused."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.sim.gate import GateConfig, TwinGate
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.strain import FlipProbe, SkinTwin, flip_probe, probe_dots, probe_dots_at


def _plain_dots(skin: SkinTwin, world: np.ndarray, offsets: np.ndarray, probe: FlipProbe) -> np.ndarray:
    """`measure_one`'s posing and face arithmetic, x / y / z one array each, on the probe's triangles."""
    mats = skin._mats(world).astype(np.float32)
    m = (mats.T @ skin._fw_t32)[:, probe.verts]
    o = offsets.T.astype(np.float32)[:, probe.verts]
    rv = skin._frest_vt32[:, probe.verts]
    x, y, z = rv[0] + o[0], rv[1] + o[1], rv[2] + o[2]
    px = m[0] * x + m[1] * y + m[2] * z + m[3]
    py = m[4] * x + m[5] * y + m[6] * z + m[7]
    pz = m[8] * x + m[9] * y + m[10] * z + m[11]
    r = (mats.T @ skin._ffw_t32)[:, probe.faces]
    n0, n1, n2 = skin._fn32[:, probe.faces]
    ex = r[0] * n0 + r[1] * n1 + r[2] * n2
    ey = r[4] * n0 + r[5] * n1 + r[6] * n2
    ez = r[8] * n0 + r[9] * n1 + r[10] * n2
    f0, f1, f2 = probe.corners
    ux, uy, uz = px[f1] - px[f0], py[f1] - py[f0], pz[f1] - pz[f0]
    wx, wy, wz = px[f2] - px[f0], py[f2] - py[f0], pz[f2] - pz[f0]
    return np.asarray((uy * wz - uz * wy) * ex + (uz * wx - ux * wz) * ey + (ux * wy - uy * wx) * ez)


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
        assert np.array_equal(skin.measure_one_faces(world[0], offsets, static)[3], dots <= 0.0)
        assert np.array_equal(dots.view(np.uint32), _plain_dots(skin, world[0], offsets, everything).view(np.uint32))
        assert int(np.count_nonzero(dots <= 0.0)) + skin.const_flips + static[2] == flips
        flipped_poses += flips > 0
        pick = np.sort(rng.choice(skin.n_measured_faces, size=int(rng.integers(1, 40)), replace=False))
        sub = probe_dots(skin, world[0], offsets, flip_probe(skin, pick))
        assert np.array_equal(sub.view(np.uint32), dots[pick].view(np.uint32))
    assert flipped_poses >= 5  # the poses flip triangles: the counts are not all zero


def test_probe_of_another_subset_is_refused(gate: TwinGate) -> None:
    probe = flip_probe(gate.skin, np.arange(3))
    stale = type(probe)(probe.subset - 1, probe.faces, probe.verts, probe.corners, probe.normals, probe.rest32)
    _, _, world, pulls = gate._pose_arrays(gate.table.neutral_tick[None, :])
    offsets = gate.skin_source.offsets_rows(pulls[0], gate.skin.fast_vertices)
    with pytest.raises(GateConfigError):
        probe_dots(gate.skin, world[0], offsets, stale)


def test_probe_offsets_of_a_few_rows_equal_the_whole_rows_gathered(gate: TwinGate) -> None:
    """`SkinSource.offsets_part` (the probe's vertices only) equals `offsets_rows` of every measured vertex
    gathered at those rows, bit for bit, on random pulls (inside and beyond the actuator ranges) and random
    row subsets; so `probe_dots_at` on them equals `probe_dots` on the whole offsets."""
    src = gate.skin_source
    skin = gate.skin
    fast = skin.fast_vertices
    rng = np.random.default_rng(41)
    span = src.upper_mm - src.lower_mm
    for trial in range(60):
        pick = np.sort(rng.choice(len(fast), size=int(rng.integers(1, 200)), replace=False))
        part = src.rows_part(fast[pick])
        p = rng.uniform(src.lower_mm - 0.1 * span, src.upper_mm + 0.1 * span)
        if trial % 3 == 0:  # some pulls at the neutral / a bound exactly (contractions at their bounds)
            p = np.where(rng.random(len(p)) < 0.5, src.lower_mm, p)
        few = src.offsets_part(p, part)
        whole = src.offsets_rows(p, fast)
        assert np.array_equal(few.view(np.uint64), whole[pick].view(np.uint64))
        faces = np.sort(rng.choice(skin.n_measured_faces, size=int(rng.integers(1, 30)), replace=False))
        probe = flip_probe(skin, faces)
        _, _, world, _ = gate._pose_arrays(gate.table.neutral_tick[None, :] + rng.integers(-40, 41, gate.table.n))
        at = probe_dots_at(skin, world[0], src.offsets_part(p, src.rows_part(fast[probe.verts])), probe)
        assert np.array_equal(at.view(np.uint32), probe_dots(skin, world[0], whole, probe).view(np.uint32))
