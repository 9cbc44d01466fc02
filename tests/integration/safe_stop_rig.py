"""Two processes over a pty, as on a real bench: ``servoface emulate --head human`` (the far end of the wire)
and ``servoface play ... --port /dev/pts/N``; the emulator's final state (``--state-file``, written when it
is stopped) or the stock SDK over the pty says what the servos did."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
LONG_SCRIPT = "human_performance"  # ~14 s: still playing when the signal comes


def servoface(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "servoface.controller.cli", *args],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, **(env or {})},
    )


@dataclass
class Bench:
    emulator: subprocess.Popen[str]
    port: str
    state_file: Path
    lock_dir: Path
    player: subprocess.Popen[str] | None = None
    stderr_lines: list[str] = field(default_factory=list)

    def play(self, *args: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
        self.player = servoface(
            "play", *args, "--port", self.port, env={"SERVOFACE_LOCK_DIR": str(self.lock_dir), **(env or {})}
        )
        return self.player

    def wait_for(self, text: str, timeout_s: float = 240.0) -> None:
        """Read the player's stderr until a line contains ``text``."""
        assert self.player is not None and self.player.stderr is not None
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            line = self.player.stderr.readline()
            if not line:
                raise AssertionError(f"servoface ended before {text!r}: {''.join(self.stderr_lines)}")
            self.stderr_lines.append(line)
            if text in line:
                return
        raise AssertionError(f"no {text!r} within {timeout_s} s")

    def emulator_says(self, text: str, timeout_s: float = 120.0) -> None:
        """Read the emulator's stderr until a line contains ``text`` (e.g. its fault-on-signal notice)."""
        assert self.emulator.stderr is not None
        seen: list[str] = []
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            line = self.emulator.stderr.readline()
            if not line:
                raise AssertionError(f"the emulator ended before {text!r}: {''.join(seen)}")
            seen.append(line)
            if text in line:
                return
        raise AssertionError(f"no {text!r} from the emulator within {timeout_s} s")

    def finish(self, timeout_s: float = 120.0) -> tuple[int, str, str]:
        assert self.player is not None
        out, err = self.player.communicate(timeout=timeout_s)
        return self.player.returncode, out, "".join(self.stderr_lines) + err

    def final_state(self) -> dict[str, Any]:
        """Stop the emulator (SIGTERM) and read what it wrote."""
        self.emulator.send_signal(signal.SIGTERM)
        assert self.emulator.wait(timeout=30) == 0
        return json.loads(self.state_file.read_text())


@contextmanager
def bench(tmp_path: Path, *extra: str) -> Iterator[Bench]:
    state = tmp_path / "emulator-state.json"
    emulator = servoface("emulate", "--head", "human", "--state-file", str(state), *extra)
    try:
        assert emulator.stdout is not None
        port = emulator.stdout.readline().strip()
        assert port.startswith("/dev/"), emulator.stderr.read() if emulator.stderr else port
        b = Bench(emulator, port, state, tmp_path / "locks")
        yield b
    finally:
        for proc in (emulator, *([b.player] if "b" in locals() and b.player is not None else [])):
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def limits_tick() -> dict[int, tuple[int, int]]:
    from servoface.calibration import load_calibration
    from servoface.sim.heads import load_head

    head = load_head("human")
    return load_calibration(head.calibration_path).position_limits_tick()


def goals_outside_limits(state: dict[str, Any]) -> list[tuple[float, int, int]]:
    lim = limits_tick()
    return [(t, sid, g) for t, sid, g in state["goal_writes"] if not lim[sid][0] <= g <= lim[sid][1]]


def torque_on_ids(state: dict[str, Any]) -> list[int]:
    return sorted(int(sid) for sid, s in state["servos"].items() if s["torque_enable"])
