"""Calibrate one servo through the page, then `servoface calibrate` with the same captures typed at its
prompts: the two calibration files are the same (only the time they were made differs)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from tests.studio.conftest import StudioRig

ROOT = Path(__file__).resolve().parents[3]
ROLE = "jaw"
POINTS = 1  # neutral, lower, upper and one point between (the fit's coverage check wants one)
JOG_TICK = 200  # one move is at most 300 ticks from where the servo is (the procedure's safe step)


def _settled(rig: StudioRig, sid: int) -> bool:
    servo = rig.chain.servo(sid)
    return not servo.read_register("Moving") and (
        not servo.read_register("Torque Enable") or servo.position_tick == servo.read_register("Goal Position")
    )


def _calibrate_in_page(page: Any, rig: StudioRig) -> tuple[Path, list[list[str]]]:
    """Neutral, lower and upper of ROLE with the page's buttons; returns the file and what was pressed."""
    sid = int(next(s["id"] for s in rig.client.get("/api/head").json()["servos"] if s["role"] == ROLE))
    page.click('a[data-page="calibrate"]')
    page.check(f'input[data-role="{ROLE}"]')
    page.fill("#cal-points", str(POINTS))
    page.fill("#cal-out", "cal-page.json")
    page.click("#cal-start")
    pressed: list[list[str]] = []
    spec = next(s for s in rig.client.get("/api/head").json()["servos"] if s["role"] == ROLE)
    steps = 1 + (spec["lower"] != spec["neutral"]) + (spec["upper"] != spec["neutral"]) + POINTS
    for n in range(steps):
        rig.wait_for(lambda n=n: _captured(rig) == n, timeout_s=60, what=f"prompt {n + 1}")
        state = rig.client.get("/api/calibrate").json()
        step = state["prompt"]["step"]
        page.wait_for_selector(f'.calibrate[data-step="{step}"]')
        actions: list[str] = []
        suggested = state["prompt"]["suggested_tick"]
        if step != "neutral":
            while abs(suggested - rig.chain.servo(sid).position_tick) > 300:  # the long way in safe steps
                sign = 1 if suggested > rig.chain.servo(sid).position_tick else -1
                page.fill("#cal-step", str(JOG_TICK))
                asked = state["prompt"]
                page.click("#cal-jog-up" if sign > 0 else "#cal-jog-down")
                rig.wait_for(lambda a=asked: rig.client.get("/api/calibrate").json()["prompt"] != a, what="the jog")
                rig.wait_for(lambda: _settled(rig, sid), timeout_s=60, what="the servo to settle after the jog")
                actions.append(f"{sign * JOG_TICK:+d}")
                state = rig.client.get("/api/calibrate").json()
            page.click("#cal-suggested")
            actions.append("g")
            rig.wait_for(lambda s=suggested: rig.chain.servo(sid).read_register("Goal Position") == s, what="the go-to")
        rig.wait_for(lambda: _settled(rig, sid), timeout_s=60, what="the servo to settle")
        actions.append(f"@{rig.chain.servo(sid).position_tick}")  # capture here
        page.click("#cal-capture")
        pressed.append(actions)
    page.wait_for_selector('.calibrate[data-step="done"]')
    final = rig.client.get("/api/calibrate").json()
    assert final["error"] == "" and [a[-1] for a in pressed] == [f"@{c['tick']}" for c in final["captured"]]
    saved = Path(page.inner_text("#cal-saved").strip())
    assert page.inner_text("#cal-applied").startswith("In use now")  # no restart needed
    return saved, pressed


def _captured(rig: StudioRig) -> int:
    """Points captured so far while the session asks (-1 when it is not asking)."""
    state = rig.client.get("/api/calibrate").json()
    return len(state["captured"]) if state["active"] and state["prompt"] else -1


class _Cli:
    """`servoface calibrate` over pipes: read each prompt, answer it."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "servoface.controller.cli", "calibrate", *args],
            cwd=ROOT,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.text = ""
        self.seen = 0
        self._lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        while chunk := self.proc.stdout.read1(4096):
            with self._lock:
                self.text += chunk.decode("utf-8", "replace")

    def prompt(self, timeout_s: float = 180.0) -> tuple[int, str]:
        """The next prompt: (present tick, its text)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self._lock:
                at = self.text.find("): ", self.seen)
                if at >= 0:
                    start = self.text.rfind("[", 0, at)
                    line = self.text[start : at + 3]
                    self.seen = at + 3
                    return int(line.split("@ ")[1].split("]")[0]), line
            if self.proc.poll() is not None:
                break
            time.sleep(0.02)
        raise AssertionError(f"no prompt from servoface calibrate:\n{self.text[-3000:]}")

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write((line + "\n").encode())
        self.proc.stdin.flush()


def test_calibrating_one_servo_in_the_page_writes_the_file_the_cli_writes(
    studio_page: tuple[Any, StudioRig], tmp_path: Path
) -> None:
    page, rig = studio_page
    page_file, pressed = _calibrate_in_page(page, rig)
    assert page_file.is_file()

    cli_file = tmp_path / "cal-cli.json"
    cli = _Cli("--head", "human", "--emulate", "--roles", ROLE, "--points", str(POINTS), "--out", str(cli_file))
    for actions in pressed:
        present, _ = cli.prompt()
        for action in actions:
            if action.startswith("@"):
                want = int(action[1:])
                for _ in range(500):  # "+0" re-reads the present position (the servo may still be moving)
                    if present == want:
                        break
                    time.sleep(0.05)
                    cli.send("+0")
                    present, _ = cli.prompt()
                assert present == want, f"the CLI's servo stands at {present}, the page captured {want}"
                cli.send("")
            else:
                cli.send(action)
                present, _ = cli.prompt()
    assert cli.proc.wait(timeout=180) == 0, cli.text[-3000:]

    ours, theirs = json.loads(page_file.read_text()), json.loads(cli_file.read_text())
    for doc in (ours, theirs):
        doc["metadata"].pop("created_utc")  # the one field that differs: when each was made
    assert ours == theirs
    assert ROLE in json.dumps(ours["metadata"])  # the file says which servo was fitted
