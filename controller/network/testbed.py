"""Emulated heads as `servoface node` processes on loopback, and reading what their emulated servos
received (with monotonic times: one clock for every process on the machine). Used by the network tests and
by `servoface bench network`."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ENV = {**os.environ, "PYOPENGL_PLATFORM": "egl"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class NodeProc:
    name: str
    endpoint: str
    wire: Path
    log: Path
    proc: subprocess.Popen[str]

    def goals(self, servo_id: int, since_s: float = 0.0) -> list[tuple[float, int]]:
        out = []
        for line in self.wire.read_text().splitlines():
            try:
                t, sid, tick = json.loads(line)
            except ValueError:
                continue  # a line being written
            if sid == servo_id and t >= since_s:
                out.append((t, tick))
        return out

    def wait_goals(self, servo_id: int, timeout_s: float = 20.0) -> list[tuple[float, int]]:
        """The goals written so far, once there is at least one: the wire log is flushed every 50 ms
        and a loaded machine may list the head before its first frame reaches the file. Empty after
        ``timeout_s`` (or when the node exits) — the caller asserts."""
        deadline = time.monotonic() + timeout_s
        while True:
            goals = self.goals(servo_id)
            if goals or time.monotonic() >= deadline or self.proc.poll() is not None:
                return goals
            time.sleep(0.1)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()


def start_nodes(
    tmp: Path,
    names: list[str],
    *,
    users_file: Path | None = None,
    head: str = "human",
    proto: str = "tcp",
    extra: list[str] | None = None,
) -> list[NodeProc]:
    """``servoface node`` processes on loopback (``proto`` tcp or tls; ``extra``: more node arguments,
    e.g. the TLS files and ``--operators``), started when each says it is listening."""
    nodes = []
    for name in names:
        port = free_port()
        endpoint = f"{proto}/127.0.0.1:{port}"
        wire, log = tmp / f"{name}.wire", tmp / f"{name}.log"
        cmd = [
            sys.executable,
            "-m",
            "servoface.controller.cli",
            "node",
            "--head",
            head,
            "--name",
            name,
            "--site",
            "lobby",
            "--emulate",
            "--listen",
            endpoint,
            "--wire-log",
            str(wire),
            "--duration",
            "600",
        ]
        if users_file is not None:
            cmd += ["--users-file", str(users_file), "--user", "node", "--password", "node-secret"]
        cmd += list(extra or [])
        fh = log.open("w")
        proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, text=True, env=ENV)
        nodes.append(NodeProc(name, endpoint, wire, log, proc))
    deadline = time.monotonic() + 240
    for node in nodes:
        while "listening on" not in node.log.read_text():
            if node.proc.poll() is not None:
                raise RuntimeError(f"node {node.name} exited: {node.log.read_text()[-2000:]}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"node {node.name} did not start: {node.log.read_text()[-2000:]}")
            time.sleep(0.2)
    return nodes


def onset_after(goals: list[tuple[float, int]], since_s: float, *, min_change: int = 3) -> float | None:
    """The first wire time after ``since_s`` at which the goal differs from the goal at ``since_s``."""
    before = [g for t, g in goals if t <= since_s]
    if not before:
        return None
    rest = before[-1]
    for t, g in goals:
        if t > since_s and abs(g - rest) >= min_change:
            return t
    return None
