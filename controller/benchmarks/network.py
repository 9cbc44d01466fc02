"""Many heads on Zenoh, measured from each emulator's side of the wire (three `servoface node` processes on
loopback, one monotonic clock for all):

- cue onset skew: a cue to all three heads; the spread of the first goal change after the cue time, and
  the latest onset after it (5 cues; goal: spread <= 20 ms);
- a 50 Hz AU stream from another process: publish -> changed jaw goal on the wire, p99 (goal <= 30 ms),
  and the share of late frames on the head meanwhile (goal < 1 %);
- a cut link (the controller process stopped: no FIN, no keep-alives): time until the head is back at
  rest (goal <= 1 s);
- a killed node: time until it is gone from the presence list (goal <= 1 s).
"""

from __future__ import annotations

import json
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from servoface.controller.benchmarks.figure import Figure

SENDER = """
import json, sys, time
from servoface.controller.network.client import HeadsClient
from servoface.controller.network.keys import head_keys
from servoface.controller.network.zconfig import open_session
s = open_session(connect=[sys.argv[1]])
c = HeadsClient(s, live=True)
k = head_keys("lobby", sys.argv[2])
time.sleep(1.0)
mode = sys.argv[3]
if mode == "stream":
    steps, value, t0 = [], 0.0, time.monotonic()
    for i in range(int(sys.argv[4])):
        due = t0 + i / 50
        time.sleep(max(0.0, due - time.monotonic()))
        new = 0.5 if (i // 10) % 2 else 0.0  # a step every 0.2 s: 50 steps in 10 s
        t = time.monotonic()
        c.send_aus(k, {"AU26": new}, t_s=t)
        if new != value:
            steps.append(t)
        value = new
    print(json.dumps(steps), flush=True)
    time.sleep(0.3)
else:
    c.send(k, "express", name="surprise", transition_s=0.3, hold_s=60.0)
    print("sent", flush=True)
    time.sleep(120)
"""


def _spawn(tmp: Path, *args: str) -> subprocess.Popen[str]:
    from servoface.controller.network.testbed import ENV

    script = tmp / "sender.py"
    script.write_text(SENDER)
    return subprocess.Popen(
        [sys.executable, str(script), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV
    )


def run(quick: bool = False) -> Iterator[Figure]:
    from servoface.controller.network.client import HeadsClient
    from servoface.controller.network.keys import head_keys
    from servoface.controller.network.testbed import onset_after, start_nodes
    from servoface.controller.network.zconfig import open_session
    from servoface.sim.heads import load_head

    head = load_head("human")
    brow, jaw = head.servo_ids["brow_inner_l"], head.servo_ids["jaw"]
    with tempfile.TemporaryDirectory(prefix="servoface-bench-net-") as tmp_name:
        tmp = Path(tmp_name)
        nodes = start_nodes(tmp, ["h1", "h2", "h3"])
        session = open_session(connect=[n.endpoint for n in nodes])
        client = HeadsClient(session)
        try:
            deadline = time.monotonic() + 30
            while len(client.heads("lobby/*")) < 3 and time.monotonic() < deadline:
                time.sleep(0.3)
            # -- cues
            spreads, latest = [], []
            for _ in range(2 if quick else 5):
                result = client.cue(
                    "lobby/*", {"verb": "express", "name": "surprise", "transition_s": 0.3, "hold_s": 0.3}, in_s=0.8
                )
                cue_t = result["at_monotonic_s"]
                time.sleep(1.8)
                onsets = [onset_after(n.goals(brow, cue_t - 1.0), cue_t - 0.3) for n in nodes]
                if all(o is not None for o in onsets):
                    arr = np.array(onsets, dtype=float)
                    spreads.append((arr.max() - arr.min()) * 1e3)
                    latest.append((arr.max() - cue_t) * 1e3)
                for n in nodes:
                    client.send(head_keys("lobby", n.name), "neutral")
                time.sleep(1.0)
            yield Figure(
                "cue onset skew across 3 heads (median of cues)",
                statistics.median(spreads) if spreads else float("nan"),
                "ms",
                goal=20.0,
                better="lower",
                note=f"{len(spreads)} cues; spreads {[round(s, 1) for s in spreads]} ms; latest onset "
                f"after the cue time {[round(x, 1) for x in latest]} ms",
            )
            # -- a 50 Hz stream from another process
            before = client.status(head_keys("lobby", "h1"))
            sender = _spawn(tmp, nodes[0].endpoint, "h1", "stream", "150" if quick else "500")
            out, err = sender.communicate(timeout=120)
            steps = json.loads(out.strip().splitlines()[-1]) if out.strip() else []
            after = client.status(head_keys("lobby", "h1"))
            goals = nodes[0].goals(jaw, (steps[0] - 1.0) if steps else 0.0)
            lat = [o - t for t in steps if (o := onset_after(goals, t - 0.001, min_change=1)) is not None]
            lat_ms = np.array(lat) * 1e3
            frames = max(after["frames"] - before["frames"], 1)
            late = (after["late"] - before["late"]) / frames
            yield Figure(
                "50 Hz AU stream: publish -> goal on the wire, p99",
                float(np.percentile(lat_ms, 99)) if len(lat_ms) else float("nan"),
                "ms",
                goal=30.0,
                better="lower",
                note=f"{len(lat_ms)} steps of the jaw; median {np.median(lat_ms):.1f} ms",
            )
            yield Figure(
                "late frames on the head during the stream",
                late * 100,
                "%",
                goal=1.0,
                better="lower",
                note=f"{after['late'] - before['late']} of {frames} frames",
            )
            # -- a cut link
            ctl = _spawn(tmp, nodes[1].endpoint, "h2", "express")
            assert ctl.stdout is not None
            ctl.stdout.readline()
            time.sleep(1.2)
            rest = nodes[1].goals(brow, 0.0)[0][1]
            ctl.send_signal(signal.SIGSTOP)
            cut = time.monotonic()
            time.sleep(2.0)
            back = [t for t, g in nodes[1].goals(brow, cut) if abs(g - rest) <= 2]
            ctl.send_signal(signal.SIGCONT)
            ctl.kill()
            ctl.wait(10)
            yield Figure(
                "cut link -> head back at rest",
                (back[0] - cut) * 1e3 if back else float("nan"),
                "ms",
                goal=1000.0,
                better="lower",
                note="controller stopped (SIGSTOP): lease 400 ms + 0.3 s ease",
            )
            # -- a killed node
            nodes[2].proc.send_signal(signal.SIGKILL)
            t0 = time.monotonic()
            nodes[2].proc.wait(10)
            gone = float("nan")
            while time.monotonic() - t0 < 5.0:
                if "h3" not in [h.name for h in client.heads("lobby/*", timeout_s=0.3)]:
                    gone = (time.monotonic() - t0) * 1e3
                    break
                time.sleep(0.02)
            yield Figure(
                "killed node -> gone from `servoface heads`",
                gone,
                "ms",
                goal=1000.0,
                better="lower",
                note="presence: Zenoh liveliness token, dropped with the node's link",
            )
        finally:
            session.close()
            for n in nodes:
                n.stop()
