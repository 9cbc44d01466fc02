"""The scale and interleave benchmarks' pieces (figures are printed by `servoface bench`, never asserted on time)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from servoface.controller.benchmarks import interleave, scale
from servoface.sim.heads import load_head


def test_a_subdivided_human_profile_loads_with_four_times_the_skin(tmp_path: Path) -> None:
    base = load_head("human")
    head = load_head(scale.subdivided_profile(1, tmp_path / "sub1"))
    n0, n1 = len(base.skin.vertices_mm), len(head.skin.vertices_mm)
    assert 3.5 * n0 < n1 < 4.5 * n0
    assert len(head.skin.faces) == 4 * len(base.skin.faces)
    assert [m.name for m in head.muscles] == [m.name for m in base.muscles]
    assert [a.role for a in head.actuators] == [a.role for a in base.actuators]


def test_growth_exponent_is_one_for_linear_costs() -> None:
    assert scale.exponent([1.0, 4.0, 16.0], [2.0, 8.0, 32.0]) == pytest.approx(1.0)
    assert scale.exponent([1.0, 16.0], [1.0, 4.0]) == pytest.approx(0.5)
    assert math.isnan(scale.exponent([1.0], [1.0]))


def test_interleaved_windows_rotate_and_ratio_to_the_reference() -> None:
    calls: list[str] = []
    out = interleave.interleaved(
        {"ref": lambda n: calls.append("ref"), "other": lambda n: calls.append("other")}, "ref", 3, 0.002, warm=1
    )
    assert len(out["ref"].rates) == len(out["other"].ratios) == 3
    assert out["ref"].ratios == [1.0, 1.0, 1.0] and out["other"].median_ratio > 0
    assert "ref" in calls and "other" in calls
    with pytest.raises(ValueError, match="reference"):
        interleave.interleaved({"a": lambda n: None}, "b", 1, 0.001)
    assert "load" in interleave.load_text()


def test_interleaved_windows_settle_before_timing_and_keep_counting() -> None:
    """``settle`` steps run at the start of every window (untimed) for every contender; the counter each
    contender gets keeps running through them (no step number is used twice)."""
    seen: dict[str, list[int]] = {"ref": [], "other": []}
    out = interleave.interleaved(
        {name: (lambda n, name=name: seen[name].append(n)) for name in seen}, "ref", 3, 0.001, warm=0, settle=4
    )
    for name, ns in seen.items():
        assert ns == list(range(len(ns))) and len(ns) >= 3 * 5, name  # 4 settling + at least 1 timed per window
        assert out[name].count == len(ns)


def test_own_clock_runs_only_in_its_contenders_windows() -> None:
    """A contender's `OwnClock` advances during its own windows and warm-up only: the other contender's
    windows (here a sleeping one) do not count, so its windows join up; it runs again afterwards."""
    clock = interleave.OwnClock()
    stamps: list[float] = []

    def mine(_: int) -> None:
        stamps.append(clock())

    def other(_: int) -> None:
        time.sleep(0.004)

    t0, c0 = time.monotonic(), clock()
    interleave.interleaved({"mine": mine, "other": other}, "other", 4, 0.01, warm=1, clocks={"mine": clock})
    wall_s, own_s = time.monotonic() - t0, clock() - c0
    assert wall_s > 0.075  # 4 windows of each contender at least
    assert own_s < 0.7 * wall_s  # the other's windows are not in it
    assert own_s > 0.035  # its own four windows are
    gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    assert max(gaps) < 0.01  # no step saw the other's windows (>= 12 ms each) go by
    before = clock()
    time.sleep(0.01)
    assert clock() - before >= 0.009  # running again on return


def test_own_clock_stands_still_while_paused() -> None:
    clock = interleave.OwnClock()
    clock.pause()
    at = clock()
    time.sleep(0.005)
    assert clock() == at
    clock.pause()  # idempotent
    clock.resume()
    clock.resume()
    time.sleep(0.005)
    assert 0.004 < clock() - at < 0.5
