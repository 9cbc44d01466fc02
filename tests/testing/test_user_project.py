"""A robot builder's own project, outside the repo, tested with servoface's installed test kit.

The project (written to a temporary folder) has its own pyproject.toml depending on servoface, its own
module that opens a port by path and drives servos with the stock dynamixel_sdk (no servoface imports), and
its own tests that use only the plugin's fixtures and assertions (no conftest). servoface's wheel is installed
into a fresh venv (the session's one, tests/conftest.py ``wheel_venv``), the project into the same venv, and
its pytest runs there: the safe tests pass, the deliberately unsafe ones (a goal outside the limits, a torque
left on) fail with messages naming the servo, and the same tests run on "real servos" given by
--servoface-port (an emulated chain served on a pty, standing in for the USB adapter).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from servoface.testing import ChainSpec, ServedChain, load_head_and_calibration

from tests.testing.junit import outcomes
from tests.wheel_venv import run

PYPROJECT = """
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "dogjaw"
version = "0.1.0"
requires-python = ">=3.11"
dependencies = ["servoface", "dynamixel-sdk"]

[tool.setuptools]
py-modules = ["dogjaw"]

[tool.pytest.ini_options]
testpaths = ["tests"]
servoface_head = "dog"        # the built-in dog head: XL330-M288, XL430-W250 and XM430-W350 servos
servoface_transport = "pty"   # served by another process; my code opens it by path
"""

MODULE = '''
"""Open and close a dog head's mouth: my own code, on the stock dynamixel_sdk (Protocol 2.0)."""

import time

from dynamixel_sdk import COMM_SUCCESS, GroupSyncWrite, PacketHandler, PortHandler

TORQUE_ENABLE, GOAL_POSITION, PRESENT_POSITION = 64, 116, 132
TRIES = 3  # a reply lost on a busy line is asked for again


class Mouth:
    def __init__(self, port: str, ids: list[int], baud: int = 1_000_000) -> None:
        self.port = PortHandler(port)
        if not self.port.openPort() or not self.port.setBaudRate(baud):
            raise OSError(f"cannot open {port} at {baud} bps")
        self.packet = PacketHandler(2.0)
        self.ids = list(ids)
        self.goals: dict[int, int] = {}

    def answering(self) -> list[int]:
        ok = [sid for sid in self.ids if any(self.packet.ping(self.port, sid)[1] == COMM_SUCCESS for _ in range(TRIES))]
        return ok

    def present(self, sid: int) -> int:
        for _ in range(TRIES):
            value, comm, _ = self.packet.read4ByteTxRx(self.port, sid, PRESENT_POSITION)
            if comm == COMM_SUCCESS:
                return value - (1 << 32) if value >= 1 << 31 else value
        raise OSError(f"servo {sid}: {self.packet.getTxRxResult(comm)}")

    def enable(self) -> None:
        """Goal := Present Position first, then torque on: no jump."""
        for sid in self.ids:
            self.goals[sid] = self.present(sid)
            self.packet.write4ByteTxRx(self.port, sid, GOAL_POSITION, self.goals[sid])
            self.packet.write1ByteTxRx(self.port, sid, TORQUE_ENABLE, 1)

    def move(self, goals: dict[int, int], step_tick: int = 12, period_s: float = 0.02) -> None:
        """Ramp every servo to its goal, at most ``step_tick`` per frame, one Sync Write per frame."""
        while any(self.goals[sid] != goal for sid, goal in goals.items()):
            frame = GroupSyncWrite(self.port, self.packet, GOAL_POSITION, 4)
            for sid, goal in goals.items():
                here = self.goals[sid]
                self.goals[sid] = here + max(-step_tick, min(step_tick, goal - here))
                frame.addParam(sid, list(self.goals[sid].to_bytes(4, "little", signed=True)))
            frame.txPacket()
            time.sleep(period_s)

    def jump(self, sid: int, goal: int) -> None:
        self.packet.write4ByteTxRx(self.port, sid, GOAL_POSITION, goal)
        self.goals[sid] = goal

    def release(self) -> None:
        for sid in self.ids:
            self.packet.write1ByteTxRx(self.port, sid, TORQUE_ENABLE, 0)

    def close(self) -> None:
        self.port.closePort()
'''

SAFE_TESTS = """
import pytest
from dogjaw import Mouth


@pytest.mark.hardware(emulate=True)  # on the emulator here; on the bench with --servoface-port /dev/ttyUSB0
def test_open_and_close_the_mouth(servo_port, calibration, servo_wire):
    jaw, ear = calibration["jaw"], calibration["ear_pan_l"]
    mouth = Mouth(servo_port, [jaw.servo_id, ear.servo_id])
    try:
        mouth.enable()
        mouth.move({jaw.servo_id: jaw.neutral_tick + 150, ear.servo_id: ear.neutral_tick + 100})
        servo_wire.assert_final_positions(
            {jaw.servo_id: jaw.neutral_tick + 150, ear.servo_id: ear.neutral_tick + 100}, within_s=3.0
        )
        mouth.move({jaw.servo_id: jaw.neutral_tick, ear.servo_id: ear.neutral_tick})
        mouth.release()
    finally:
        mouth.close()
    servo_wire.assert_safe()
    servo_wire.assert_torque_off()


def test_a_silent_servo_is_not_reported_as_answering(servo_chain, servo_port, calibration):
    jaw, ear = calibration.id_of("jaw"), calibration.id_of("ear_pan_l")
    servo_chain.inject(jaw, "no_reply", after_s=0.0, duration_s=None)
    mouth = Mouth(servo_port, [jaw, ear])
    try:
        assert mouth.answering() == [ear]
        servo_chain.clear_faults(jaw)
        assert mouth.answering() == [jaw, ear]
    finally:
        mouth.close()


@pytest.mark.servoface(clock="manual")
def test_the_jaw_moves_only_as_time_passes(servo_chain, servo_port, calibration, servo_wire):
    jaw = calibration["jaw"]
    mouth = Mouth(servo_port, [jaw.servo_id])
    try:
        mouth.enable()
        mouth.jump(jaw.servo_id, jaw.neutral_tick + 20)  # one frame from rest: within the speed-up bound
        assert mouth.present(jaw.servo_id) == jaw.neutral_tick
        servo_chain.advance(1.0)
        assert mouth.present(jaw.servo_id) == jaw.neutral_tick + 20
        mouth.release()
    finally:
        mouth.close()
    servo_wire.assert_safe()
    servo_wire.assert_torque_off()


@pytest.mark.hardware
def test_on_the_bench_only(servo_port, calibration):
    mouth = Mouth(servo_port, [calibration.id_of("jaw")])
    try:
        assert mouth.answering() == [calibration.id_of("jaw")]
    finally:
        mouth.close()
"""

UNSAFE_TESTS = """
from dogjaw import Mouth


def test_unsafe_goal_outside_the_limits(servo_port, calibration, servo_wire):
    jaw = calibration["jaw"]
    mouth = Mouth(servo_port, [jaw.servo_id])
    try:
        mouth.enable()
        mouth.move({jaw.servo_id: jaw.max_tick + 60})  # past the calibrated limit: the jaw would hit its stop
        mouth.move({jaw.servo_id: jaw.neutral_tick})
        mouth.release()
    finally:
        mouth.close()
    servo_wire.assert_safe()


def test_unsafe_torque_left_on(servo_port, calibration, servo_wire):
    jaw = calibration["jaw"]
    mouth = Mouth(servo_port, [jaw.servo_id])
    try:
        mouth.enable()
        mouth.move({jaw.servo_id: jaw.neutral_tick + 60})
    finally:
        mouth.close()  # forgot mouth.release()
    servo_wire.assert_safe()
    servo_wire.assert_torque_off()
"""


@pytest.fixture(scope="module")
def project(wheel_venv: tuple[Path, Path, dict[str, str]]) -> tuple[Path, Path, dict[str, str]]:
    """(venv python, project folder, environment): the project installed next to servoface's wheel."""
    python, base, env = wheel_venv
    folder = base / "dogjaw"
    (folder / "tests").mkdir(parents=True)
    (folder / "pyproject.toml").write_text(PYPROJECT)
    (folder / "dogjaw.py").write_text(MODULE)
    (folder / "tests" / "test_mouth.py").write_text(SAFE_TESTS)
    (folder / "tests" / "test_unsafe.py").write_text(UNSAFE_TESTS)
    pip = [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    run([*pip, f"pytest=={pytest.__version__}", "setuptools>=70.1"], folder, env, 600)  # 70.1: bdist_wheel built in
    run([*pip, "--no-build-isolation", "--no-deps", str(folder)], folder, env, 600)
    run([str(python), "-m", "pip", "check"], folder, env)  # servoface (from the wheel) satisfies dogjaw's dependency
    return python, folder, env


def _pytest(project: tuple[Path, Path, dict[str, str]], *args: str, report: str) -> dict[str, tuple[str, str]]:
    python, folder, env = project
    env = {k: v for k, v in env.items() if not k.startswith("SERVOFACE_")}
    proc = subprocess.run(
        [str(python), "-m", "pytest", "-p", "no:cacheprovider", "-rs", f"--junitxml={folder / report}", *args],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode in (0, 1), f"pytest exited {proc.returncode}\n{proc.stdout[-4000:]}\n{proc.stderr[-3000:]}"
    return outcomes(folder / report)


@pytest.mark.slow
def test_the_kit_is_installed_with_the_wheel(project: tuple[Path, Path, dict[str, str]]) -> None:
    python, folder, env = project
    assert not list(folder.rglob("conftest.py"))
    code = (
        "import importlib.metadata as m, servoface.testing.plugin as p; "
        "print(p.__file__); print([e.value for e in m.entry_points(group='pytest11') if e.name == 'servoface'])"
    )
    out = run([str(python), "-c", code], folder, env).stdout
    assert "site-packages/servoface/testing/plugin.py" in out and "['servoface.testing.plugin']" in out, out
    wheel = next((folder.parent / "dist").glob("servoface-*.whl"))
    import zipfile

    names = zipfile.ZipFile(wheel).namelist()
    assert "servoface/testing/plugin.py" in names and not any(
        n.startswith("servoface/controller/testing") for n in names
    )


@pytest.mark.slow
def test_the_projects_own_tests_pass_and_the_unsafe_ones_fail_naming_the_servo(
    project: tuple[Path, Path, dict[str, str]],
) -> None:
    got = _pytest(project, report="emulator.xml")
    for name in (
        "test_open_and_close_the_mouth",
        "test_a_silent_servo_is_not_reported_as_answering",
        "test_the_jaw_moves_only_as_time_passes",
    ):
        assert got[name][0] == "passed", (name, got[name][1][-3000:])
    outcome, text = got["test_on_the_bench_only"]
    assert outcome == "skipped" and "--servoface-port /dev/ttyUSB0" in text, got["test_on_the_bench_only"]
    _, jaw_cal = load_head_and_calibration("dog")
    jaw = jaw_cal["jaw"]
    outcome, text = got["test_unsafe_goal_outside_the_limits"]
    assert outcome == "failed", got["test_unsafe_goal_outside_the_limits"]
    assert f"servo {jaw.servo_id} 'jaw': goal {jaw.max_tick + 60} tick outside its calibration limits" in text, text
    assert f"{jaw.min_tick}..{jaw.max_tick} tick" in text
    outcome, text = got["test_unsafe_torque_left_on"]
    assert outcome == "failed", got["test_unsafe_torque_left_on"]
    assert f"servo {jaw.servo_id} 'jaw': torque left on at the end, expected off" in text, text


@pytest.mark.slow
def test_the_same_tests_on_servos_given_by_port(project: tuple[Path, Path, dict[str, str]]) -> None:
    """--servoface-port: the hardware tests run on the servos there (the dog head's chain served on a pty
    by another process stands in for the USB adapter); the others are not collected by ``-m hardware``."""
    head, cal = load_head_and_calibration("dog")
    servos = tuple((s.servo_id, s.model) for s in cal.servos)
    with ServedChain(ChainSpec(servos, positions_tick=cal.neutral_goals())) as bench:
        got = _pytest(
            project, "-m", "hardware", "--servoface-port", bench.path, "--servoface-head", "dog", report="bench.xml"
        )
        assert set(got) == {"test_open_and_close_the_mouth", "test_on_the_bench_only"}, got
        assert all(outcome == "passed" for outcome, _ in got.values()), got
        record = bench.record()
    jaw = cal.id_of("jaw")
    assert max(g.goal_tick for g in record.goals if g.servo_id == jaw) == cal["jaw"].neutral_tick + 150
    assert not record.end[jaw].torque_on
