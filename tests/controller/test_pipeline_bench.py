"""`servoface bench pipeline --json --quick` runs end to end and prints figures next to their limits."""

from __future__ import annotations

import json

import pytest
from servoface.controller.cli import main
from servoface.hardware.wire import cycle_budget


def test_bench_pipeline_prints_figures_against_the_wire_limit(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "pipeline", "--json", "--quick"]) == 0
    figures = {d["name"]: d for d in map(json.loads, capsys.readouterr().out.splitlines())}
    fps = next(d for name, d in figures.items() if name.startswith("pipeline frames/s"))
    assert fps["unit"] == "frames/s" and fps["value"] > 0
    # 30 goals written, 33 positions read: a little less traffic than a full 33-servo cycle
    assert cycle_budget(33, 1_000_000).limit_hz < fps["limit"] < cycle_budget(30, 1_000_000).limit_hz
    assert fps["ratio"] == pytest.approx(fps["value"] / fps["limit"], rel=1e-3)
    assert "corrupt 0" in fps["note"]
    stages = {name.rsplit(" ", 1)[-1]: d for name, d in figures.items() if name.startswith("pipeline stage median")}
    assert set(stages) == {"muscle", "calibration", "gate", "bus", "total"}
    assert all(stages[s]["value"] < stages["total"]["value"] for s in ("muscle", "calibration", "gate", "bus"))
    assert stages["gate"]["limit"] == 1.0 and stages["bus"]["limit"] == pytest.approx(1e3 / fps["limit"])


def test_bench_with_no_suite_runs_the_quick_default_set_and_all_runs_every_short_suite() -> None:
    from servoface.controller.benchmarks import DEFAULT_SUITES, LONG_SUITES, SUITES
    from servoface.controller.cli.bench import suite_names

    assert suite_names([]) == list(DEFAULT_SUITES)
    assert set(DEFAULT_SUITES) <= set(SUITES) and not {"pty", "network", "soak"} & set(DEFAULT_SUITES)
    assert suite_names(["all"]) == [n for n in SUITES if n not in LONG_SUITES]
    assert suite_names(["all", "soak"])[-1] == "soak" and suite_names(["gate"]) == ["gate"]
