"""`servoface studio` ends safe however it is stopped, checked from the emulator's side of a real pty: a
signal eases the head to neutral and turns every torque off; Ctrl-C twice hurries the ease, it does not skip
it (the second signal used to raise inside the shutdown: every servo stayed powered, mid-expression); the
twin's render process, which gets the terminal's Ctrl-C too, ends without a traceback of its own."""

from __future__ import annotations

import json
import signal
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from tests.integration.safe_stop_rig import bench, goals_outside_limits, servoface, torque_on_ids

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")


def _express(url: str, name: str) -> None:
    """POST /api/express with the run's token (the URL's ``?token=``), as the page does."""
    base, token = url.split("/?token=") if "/?token=" in url else url.split("?token=")
    request = urllib.request.Request(
        f"{base.rstrip('/')}/api/express",
        data=json.dumps({"name": name, "hold_s": 30}).encode(),
        headers={"Authorization": f"Bearer {token}", "Content-Type": "application/json"},
        method="POST",
    )
    with urllib.request.urlopen(request, timeout=30) as reply:
        assert reply.status == 202  # accepted: the command runs on the head service


@pytest.mark.parametrize("signals", [1, 2], ids=["ctrl-c", "ctrl-c-twice"])
def test_a_stopped_studio_leaves_every_servo_limp_at_neutral(tmp_path: Path, signals: int) -> None:
    with bench(tmp_path) as b:
        b.player = servoface("studio", "--head", "human", "--port", b.port, "--port-http", "0")
        assert b.player.stdout is not None
        deadline = time.monotonic() + 240
        url = ""
        while not url and time.monotonic() < deadline:
            line = b.player.stdout.readline()
            assert line, f"studio ended early: {b.player.stderr.read() if b.player.stderr else ''}"
            url = line.split("open ", 1)[1].strip() if line.startswith("open ") else ""
        _express(url, "surprise")
        time.sleep(1.5)  # the head is in the expression, away from neutral
        for _ in range(signals):
            b.player.send_signal(signal.SIGINT)
            time.sleep(0.05)
        status, out, err = b.finish()
        state = b.final_state()
    assert status == 130, out + err
    assert "stop (SIGINT)" in out and "torque off on every servo" in out, out + err
    assert "Traceback" not in err, err
    assert torque_on_ids(state) == [], state["servos"]
    assert goals_outside_limits(state) == []
    moved = [g for _, _, g in state["goal_writes"]]
    assert len(set(moved)) > 30, "the expression moved the head before the stop"
