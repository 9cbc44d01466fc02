"""The stock-SDK example script against `servoface emulate` in a subprocess, over a real pty."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.registers import Register

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("fault", [None, "2:no_reply*1"], ids=["clean", "one-lost-reply"])
def test_stock_sdk_script_moves_emulated_servos(fault: str | None) -> None:
    """Also with servo 2's first reply lost (its ping's): the example asks again, as a script on a real bus
    must (a lost reply is not a missing servo)."""
    emulator = subprocess.Popen(
        [sys.executable, "-m", "servoface.controller.cli", "emulate", "--ids", "1-4", "--model", "XL330-M288"]
        + ([] if fault is None else ["--fault", fault]),
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert emulator.stdout is not None
        path = emulator.stdout.readline().strip()
        assert path.startswith("/dev/"), f"emulator printed {path!r}; exit {emulator.poll()}"
        script = subprocess.run(
            [sys.executable, str(ROOT / "examples" / "stock_sdk_over_pty.py"), path, "--ids", "1,2,3,4"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert script.returncode == 0, script.stdout + script.stderr
        assert "moved:" in script.stdout and "fast sync read" in script.stdout
        # independently: the emulated servos are where the script sent them (2048 - 300), torque on
        with open_bus("dynamixel", port=path, baud=1_000_000) as bus:
            got = bus.sync_read([1, 2, 3, 4], [Register.PRESENT_POSITION, Register.GOAL_POSITION])
            assert all(v[Register.PRESENT_POSITION] == 1748 == v[Register.GOAL_POSITION] for v in got.values())
            assert all(bus.read(sid, Register.TORQUE_ENABLE) == 1 for sid in (1, 2, 3, 4))
    finally:
        emulator.terminate()
        try:
            emulator.wait(timeout=10)
        except subprocess.TimeoutExpired:
            emulator.kill()
            emulator.wait()
    assert emulator.returncode == 0
