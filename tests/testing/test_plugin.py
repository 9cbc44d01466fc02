"""The plugin as another project meets it (a pytest run in a temporary folder, no conftest): the hardware
marker skipped with its reason or run on the emulator, the same tests on "real servos" given by
--servoface-port (here: an emulated chain served on a pty, standing in for a USB adapter), bad markers
named."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from servoface.testing import ChainSpec, LocalChain

from tests.testing.junit import outcomes

TESTS = """
import pytest
from servoface.hardware.registers import Register


@pytest.mark.hardware(emulate=True)
def test_same_on_both(driver, servo_wire):
    driver.torque_on()
    start = driver.read_state().positions_tick()
    for k in range(1, 6):
        driver.cycle({sid: tick + 4 * k for sid, tick in start.items()})
    servo_wire.assert_final_positions({sid: tick + 20 for sid, tick in start.items()}, within_s=3.0)
    driver.torque_off()
    servo_wire.assert_safe()
    servo_wire.assert_torque_off()


@pytest.mark.hardware
def test_bench_only(dxl_bus, servo_specs):
    from servoface.hardware.scan import scan

    assert [r.model_number for r in scan(dxl_bus, [s.servo_id for s in servo_specs])] == [1200] * 4


@pytest.mark.hardware
def test_needs_the_emulator(servo_chain):
    servo_chain.inject(1, "overload")


def test_emulator_only(servo_chain, servo_port):
    assert servo_port is servo_chain.port


@pytest.mark.servoface(hed="dog")
def test_misspelt(servo_chain):
    pass
"""


def _pytest(
    folder: Path, *args: str, env: dict[str, str] | None = None
) -> tuple[subprocess.CompletedProcess[str], dict[str, tuple[str, str]]]:
    report = folder / "report.xml"
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rs", f"--junitxml={report}", *args],
        cwd=folder,
        env={k: v for k, v in os.environ.items() if not k.startswith("SERVOFACE_")} | (env or {}),
        capture_output=True,
        text=True,
        timeout=300,
    )
    return proc, outcomes(report)


@pytest.fixture
def project(tmp_path: Path) -> Path:
    (tmp_path / "test_rig.py").write_text(TESTS)
    return tmp_path


def test_without_a_port_hardware_tests_skip_with_the_reason(project: Path) -> None:
    proc, got = _pytest(project)
    assert "servoface: @pytest.mark.hardware tests need --servoface-port" in proc.stdout
    assert got["test_same_on_both"][0] == "passed", got["test_same_on_both"]
    assert got["test_emulator_only"][0] == "passed"
    for name in ("test_bench_only", "test_needs_the_emulator"):
        outcome, text = got[name]
        assert outcome == "skipped" and "give --servoface-port /dev/ttyUSB0 (or set SERVOFACE_PORT)" in text, got[name]
    outcome, text = got["test_misspelt"]
    assert outcome == "error" and "unknown argument(s) ['hed']" in text, got["test_misspelt"]


@pytest.mark.parametrize("how", ["option", "env"])
def test_with_a_port_the_same_tests_run_on_the_servos_there(project: Path, how: str) -> None:
    servos = tuple((i, "XL330-M288") for i in (1, 2, 3, 4))
    bench = LocalChain(ChainSpec(servos, wire_time=False))  # replies at once: a loaded machine is slow enough
    path = bench.chain.serve_pty()
    try:
        if how == "option":
            proc, got = _pytest(project, "--servoface-port", path, "--servoface-ids", "1-4", "-W", "default")
        else:
            proc, got = _pytest(project, "-W", "default", env={"SERVOFACE_PORT": path, "SERVOFACE_IDS": "1-4"})
        assert f"run on real servos on {path} at 1000000 bps (ids 1-4)" in proc.stdout
        assert got["test_same_on_both"][0] == "passed", got["test_same_on_both"]
        assert got["test_bench_only"][0] == "passed", got["test_bench_only"]
        outcome, text = got["test_needs_the_emulator"]
        assert outcome == "skipped" and "cannot run on real servos" in text
        assert "not checked on real servos on" in proc.stdout  # the history checks say so, not pass silently
        record = bench.record()
        assert {g.servo_id for g in record.goals} == {1, 2, 3, 4}  # the test really drove the "bench"
        assert not any(e.torque_on for e in record.end.values())
    finally:
        bench.close()


def test_the_editable_install_resolves_the_kit_to_its_folder() -> None:
    """pyproject maps controller/testing to servoface.testing; the pytest11 entry point names its plugin."""
    import importlib.metadata

    import servoface.testing
    import servoface.testing.plugin

    root = Path(__file__).resolve().parents[2]
    assert Path(servoface.testing.__file__).resolve().parent == root / "controller" / "testing"
    points = {e.name: e.value for e in importlib.metadata.entry_points(group="pytest11")}
    assert points.get("servoface") == "servoface.testing.plugin"
    assert servoface.testing.plugin.__name__ == "servoface.testing.plugin"
