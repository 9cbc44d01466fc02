"""`servoface emulate --servos/--head/--fault/--realism`, and the README's two-terminal flow for both heads.

The flow: `servoface emulate --head NAME` in one process prints the pty path; `servoface play happiness
--head NAME --port PATH` in another configures every servo (the driver pings each id and checks its model,
e-manual Protocol 2.0 Ping: model number + firmware) and plays the expression over the stock SDK.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from servoface.controller.cli.emulate_args import FaultSpec, parse_fault, parse_servos

ROOT = Path(__file__).resolve().parents[3]
pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")


def test_parse_servos_and_faults() -> None:
    pairs = parse_servos("1-3:XL330-M288,7:XL430-W250")
    assert pairs == [(1, "XL330-M288"), (2, "XL330-M288"), (3, "XL330-M288"), (7, "XL430-W250")]
    assert parse_fault("3:no_reply@2s+0.5s") == FaultSpec(3, "no_reply", 2.0, 0.5)
    assert parse_fault("5:late_reply=20ms@1s") == FaultSpec(5, "late_reply", 1.0, None, 0.02)
    assert parse_fault("4:disconnect") == FaultSpec(4, "disconnect")
    assert parse_fault("3:no_reply*2@1s") == FaultSpec(3, "no_reply", 1.0, None, None, 2)
    assert parse_fault("5:late_reply=20ms*1") == FaultSpec(5, "late_reply", 0.0, None, 0.02, 1)
    for bad in ("1-3", "1-3:", "x:XL330-M288", "1,1:XL330-M288"):
        with pytest.raises(ValueError):
            parse_servos(bad)
    for bad in ("3", "a:no_reply", "3:no_reply@-1s", "3:no_reply@2s+x", "3:no_reply=4", "3:no_reply*0", "3:no_reply*x"):
        with pytest.raises(ValueError):
            parse_fault(bad)
    with pytest.raises(ValueError, match="kind"):
        parse_fault("3:melt", frozenset({"no_reply"}))
    with pytest.raises(ValueError, match=r"only reply faults .* take \*N"):
        parse_fault("2:overload*1")


@contextmanager
def _emulate(*args: str) -> Iterator[str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "servoface.controller.cli", "emulate", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        if not path.startswith("/dev/"):
            raise AssertionError(f"emulate printed {path!r}; stderr: {proc.stderr.read() if proc.stderr else ''}")
        yield path
    finally:
        proc.terminate()
        try:
            assert proc.wait(timeout=10) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def _ping(path: str, ids: list[int]) -> dict[int, int]:
    import dynamixel_sdk as sdk

    port = sdk.PortHandler(path)
    assert port.openPort() and port.setBaudRate(1_000_000)
    ph = sdk.PacketHandler(2.0)
    out = {}
    for sid in ids:
        for _ in range(3):  # the SDK's reply window is a few ms: a loaded machine can miss a reply
            model, comm, err = ph.ping(port, sid)
            if comm == sdk.COMM_SUCCESS:
                out[sid] = model
                break
    port.closePort()
    return out


def test_servos_serves_a_mixed_chain() -> None:
    with _emulate("--servos", "1-2:XL330-M288,5:XL430-W250,6:MX-28(2.0)") as path:
        assert _ping(path, [1, 2, 3, 5, 6]) == {1: 1200, 2: 1200, 5: 1060, 6: 30}


def test_scripted_fault_silences_a_servo_for_its_window() -> None:
    """--fault 2:no_reply@0s+5s: servo 2 is silent at first, answers again after the window (a window long
    enough that a loaded machine's start-up does not eat it; then polled, not slept)."""
    with _emulate("--servos", "1-2:XL330-M288", "--fault", "2:no_reply@0s+5s", "--realism") as path:
        t0 = time.monotonic()
        assert _ping(path, [1, 2]) == {1: 1200}
        answered = {}
        while time.monotonic() - t0 < 30.0:
            answered = _ping(path, [1, 2])
            if 2 in answered:
                break
            time.sleep(0.25)
        assert answered == {1: 1200, 2: 1200}
        assert time.monotonic() - t0 > 1.0  # it was the window that ended, not a servo that never was silent


@pytest.mark.parametrize(("args", "needle"), [(["--servos", "1:XL999"], "XL999"), (["--fault", "99:no_reply"], "99")])
def test_bad_chain_or_fault_exits_2(args: list[str], needle: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "servoface.controller.cli", "emulate", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert needle in proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("head", ["human", "dog"])
def test_two_terminal_flow_for_each_built_in_head(head: str) -> None:
    """README: `servoface emulate --head NAME` in one process, `servoface play happiness --head NAME
    --port PATH` in another; the play configures every servo and ends with exit 0."""
    with _emulate("--head", head) as path:
        play = subprocess.run(
            [
                sys.executable,
                "-m",
                "servoface.controller.cli",
                "play",
                "happiness",
                "--head",
                head,
                "--port",
                path,
            ],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
    assert play.returncode == 0, play.stderr[-2000:]
    assert "frames" in play.stdout + play.stderr
