"""`servoface bench scale`: how the costs grow with the skin's vertex count and with the number of servos.

Skin: the human head at its own resolution and with its skin subdivided once and twice (midpoint
subdivision, ~4x the vertices each; a profile folder like a user's: the built-in head.toml and calibration
with the skin read from a PLY file). Per resolution: the per-frame muscle model + calibration + gate time
(offline pipeline on the shipped human performance, medians), the render time (640x480, EGL), the muscle
model build and the cold gate build (TSS tables and skin tables, empty cache). Servos: 24 / 48 / 96
emulated XL330 on one chain served from another process over a pty at 1 Mbps; `Driver.cycle`'s CPU time per
cycle in this process and its rate against the wire limit. Each series ends with its growth exponent (log
cost ratio / log size ratio between the smallest and the largest): 1 is linear; the goal is no faster than
linear.
"""

from __future__ import annotations

import math
import shutil
import statistics
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from servoface.controller.benchmarks.figure import Figure
from servoface.controller.benchmarks.interleave import load_text

HEAD = "human"
LEVELS = (0, 1, 2)  # skin subdivisions: ~5k, ~20k, ~80k vertices
SERVO_COUNTS = (24, 48, 96)
RENDER_SIZE = (640, 480)
SKIN_LINE = 'mesh = "builtin:human_skin"'


def subdivided_profile(levels: int, folder: Path) -> Path:
    """A copy of the built-in human profile in ``folder`` whose skin is subdivided ``levels`` times."""
    import trimesh
    from servoface.sim.heads import builtin_profile_dir
    from servoface.sim.heads.builtin import skin_mesh
    from trimesh.remesh import subdivide

    src = builtin_profile_dir(HEAD)
    folder.mkdir(parents=True, exist_ok=True)
    for item in src.iterdir():
        if item.is_file():
            shutil.copy2(item, folder / item.name)
    if levels == 0:
        return folder
    v, f, c = skin_mesh("human_skin")
    for _ in range(levels):
        v, f, attrs = subdivide(v, f, vertex_attributes={"color": c})  # type: ignore[no-untyped-call]
        c = attrs["color"]
    rgba = np.clip(np.round(np.asarray(c) * 255.0), 0, 255).astype(np.uint8)
    trimesh.Trimesh(v, f, vertex_colors=rgba, process=False).export(folder / "skin.ply")
    toml = (folder / "head.toml").read_text()
    if SKIN_LINE not in toml:
        raise RuntimeError(f"the human head.toml no longer has {SKIN_LINE!r}: update the scale bench")
    (folder / "head.toml").write_text(toml.replace(SKIN_LINE, 'mesh = "skin.ply"'))
    return folder


def _median(values: list[float]) -> float:
    return float(statistics.median(values)) if values else float("nan")


def mesh_costs(levels: int, folder: Path, n_frames: int, n_render: int) -> dict[str, float]:
    """Costs of one skin resolution (ms): frame stages, render, model build, cold gate build."""
    from servoface.calibration.fileformat import load_calibration
    from servoface.controller.pipeline import Pipeline
    from servoface.controller.script import SCRIPTS_DIR, load_script
    from servoface.sim.face_model import FaceModel
    from servoface.sim.gate import GateConfig, TwinGate
    from servoface.sim.heads import load_head
    from servoface.sim.muscles.slit import forget_shared_gates

    head = load_head(subdivided_profile(levels, folder / f"human_sub{levels}"))
    if head.calibration_path is None:
        raise FileNotFoundError("the copied human profile has no calibration file")
    cal = load_calibration(head.calibration_path)
    forget_shared_gates()  # level 0 is the built-in mesh, whose slit gate an earlier model may have built
    t0 = time.perf_counter()
    face = FaceModel(head)
    t1 = time.perf_counter()
    gate = TwinGate(head, cal, 1 / 50, GateConfig(cache_dir=folder / f"tss{levels}"), face_model=face)
    t2 = time.perf_counter()
    pipeline = Pipeline(head, cal, face=face, gate=gate)
    script = load_script(SCRIPTS_DIR / "human_performance.toml")
    frames = [script.sample(k / 50.0 % script.end_s) for k in range(n_frames + 3)]
    traces = [pipeline.step(fr) for fr in frames]
    per_frame = [sum(t.timings_ms[k] for k in ("muscle_ms", "calibration_ms", "gate_ms")) for t in traces[3:]]
    out = {
        "vertices": float(len(head.skin.vertices_mm)),
        "frame_ms": _median(per_frame),
        "gate_ms": _median([t.timings_ms["gate_ms"] for t in traces[3:]]),
        "muscle_ms": _median([t.timings_ms["muscle_ms"] for t in traces[3:]]),
        "model_build_ms": (t1 - t0) * 1e3,
        "gate_build_ms": (t2 - t1) * 1e3,
    }
    out["render_ms"] = _render_ms(head, face, frames, n_render)
    return out


def _render_ms(head: Any, face: Any, frames: list[Any], n_render: int) -> float:
    from servoface.sim.render.renderer import HeadRenderer

    poses = [face.solve(fr.aus) for fr in frames[:n_render]]
    renderer = HeadRenderer(*RENDER_SIZE)
    try:
        for pose in poses[:2]:  # upload meshes, compile shaders
            renderer.render(head, pose)
        times = []
        for pose in poses:
            t0 = time.perf_counter()
            renderer.render(head, pose)
            times.append((time.perf_counter() - t0) * 1e3)
    finally:
        renderer.close()
    return _median(times)


def servo_costs(n_servos: int, cycles: int) -> dict[str, float]:
    """`Driver.cycle` on ``n_servos`` emulated XL330 served from another process over a pty at 1 Mbps: this
    process's CPU ms per cycle (the emulator's own work is not in it) and the median rate over the wire
    limit of its own packets (its position read's bytes per servo: `Driver.position_read_bytes`)."""
    from servoface.controller.benchmarks.cpu import EmulatorProcess
    from servoface.hardware.bus import open_bus
    from servoface.hardware.driver import Driver
    from servoface.hardware.registers import Register
    from servoface.hardware.servo_config import ServoSpec
    from servoface.hardware.wire import cycle_budget

    emulator = EmulatorProcess("--servos", str(n_servos))
    try:
        bus = open_bus("dynamixel", port=emulator.path, baud=1_000_000, warn_latency=False)
        ids = list(range(1, n_servos + 1))
        for sid in ids:
            bus.write(sid, Register.RETURN_DELAY_TIME, 0)
        driver = Driver(bus, [ServoSpec(sid, "XL330-M288", return_delay_us=0) for sid in ids], fast_sync_read=False)
        driver.configure()
        driver.torque_on()
        for n in range(10):
            driver.cycle({sid: 2048 + (n & 1) for sid in ids})
        times, cpu0 = [], time.process_time()
        for n in range(cycles):
            goals = {sid: 2048 + (n & 1) for sid in ids}
            t0 = time.perf_counter()
            driver.cycle(goals)
            times.append(time.perf_counter() - t0)
        cpu_ms = (time.process_time() - cpu0) / cycles * 1e3
        read_len = driver.position_read_bytes
        bus.close()
    finally:
        emulator.close()
    limit_hz = cycle_budget(n_servos, 1_000_000, read_len=read_len).limit_hz
    return {"cycle_ms": cpu_ms, "wire_ratio": 1.0 / _median(times) / limit_hz}


def exponent(sizes: list[float], costs: list[float]) -> float:
    """log(cost ratio) / log(size ratio) between the smallest and the largest size (1 = linear)."""
    if len(sizes) < 2 or sizes[0] <= 0 or costs[0] <= 0 or costs[-1] <= 0 or sizes[-1] == sizes[0]:
        return float("nan")
    return math.log(costs[-1] / costs[0]) / math.log(sizes[-1] / sizes[0])


def run(quick: bool = False) -> Iterator[Figure]:
    levels = LEVELS[:2] if quick else LEVELS
    counts = SERVO_COUNTS[:2] if quick else SERVO_COUNTS
    n_frames, n_render, cycles = (20, 6, 40) if quick else (150, 30, 300)
    load = load_text()
    with tempfile.TemporaryDirectory(prefix="servoface-scale-") as tmp:
        rows = [mesh_costs(level, Path(tmp), n_frames, n_render) for level in levels]
    sizes = [r["vertices"] for r in rows]
    labels = {
        "frame_ms": "muscle + calibration + gate per frame",
        "gate_ms": "gate per frame",
        "render_ms": f"render {RENDER_SIZE[0]}x{RENDER_SIZE[1]}",
        "model_build_ms": "muscle model build",
        "gate_build_ms": "cold gate build (TSS + skin tables)",
    }
    for key, label in labels.items():
        for row in rows:
            yield Figure(
                f"{label}, human skin {row['vertices']:.0f} vertices",
                row[key],
                "ms",
                better="lower",
                limit=5000.0 if key == "gate_build_ms" else None,
                note=f"median over {n_frames} frames of the shipped performance" if key.endswith("frame_ms") else load,
            )
        yield _growth(f"{label} vs skin vertices", sizes, [r[key] for r in rows], load)
    servo_rows = [servo_costs(n, cycles) for n in counts]
    for n, row in zip(counts, servo_rows, strict=True):
        yield Figure(
            f"Driver.cycle CPU per cycle, {n} emulated servos (emulator in another process)",
            row["cycle_ms"],
            "ms",
            better="lower",
            note=f"this process's CPU time over {cycles} cycles at 1 Mbps over a pty; {load}",
        )
        yield Figure(
            f"Driver.cycle vs wire limit, {n} emulated servos @1M over a pty",
            row["wire_ratio"],
            "x wire limit",
            note=f"1 / median cycle over the sync write + sync read wire limit for {n} servos (of its own "
            f"packets: `Driver.position_read_bytes` per servo read); {load}",
        )
    yield _growth("Driver.cycle CPU vs servos", [float(n) for n in counts], [r["cycle_ms"] for r in servo_rows], load)


def _growth(name: str, sizes: list[float], costs: list[float], load: str) -> Figure:
    pairs = ", ".join(f"{s:.0f}: {c:.3g}" for s, c in zip(sizes, costs, strict=True))
    return Figure(
        f"growth exponent, {name}",
        exponent(sizes, costs),
        "exponent",
        goal=1.0,
        better="lower",
        note=f"log(cost ratio)/log(size ratio), smallest to largest (1 = linear; lower: sub-linear); {pairs}; {load}",
    )
