"""`servoface emulate`: first line is the pty path, serves until SIGTERM/SIGINT (exit 0), bad args exit 2."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from servoface.controller.cli.emulate import parse_ids

ROOT = Path(__file__).resolve().parents[3]


def test_parse_ids_ranges_and_lists() -> None:
    assert parse_ids("1-4,7,10-12") == [1, 2, 3, 4, 7, 10, 11, 12]
    assert parse_ids("5") == [5]
    for bad in ("", "1-", "a", "4-1", "1,1", "300", "1,,2"):
        with pytest.raises(ValueError):
            parse_ids(bad)


def _start(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "servoface.controller.cli", "emulate", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_prints_path_first_then_serves_until_signal(sig: int) -> None:
    import serial
    from servoface.hardware.emulator import build_instruction

    proc = _start("--ids", "1-3,7", "--model", "XL430-W250", "--baud", "1000000")
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/") and os.path.exists(path)
        with serial.Serial(path, 1_000_000, timeout=0.05) as port:
            port.write(build_instruction(7, 0x01))
            data = b""
            deadline = time.monotonic() + 3.0
            while len(data) < 14 and time.monotonic() < deadline:
                data += port.read(14 - len(data))
            assert data[4] == 7 and data[9:11] == (1060).to_bytes(2, "little")
        proc.send_signal(sig)
        assert proc.wait(timeout=5) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize("args", [["--ids", "1-x"], ["--model", "XL999"], ["--baud", "12345"], ["--ids", "0-300"]])
def test_invalid_arguments_exit_2_with_a_message(args: list[str]) -> None:
    proc = _start(*args)
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == 2
    assert out == ""
    assert "emulate" in err and len(err.strip()) > 10
