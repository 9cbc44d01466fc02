"""The main job on the embedded default: a built-in head on the emulated chain plays a scripted
performance through the whole pipeline (wire time on); the twin's view is written as a video, the
expression library as a contact sheet, and what happened as ``report.json``.
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from servoface.controller.face import Face
from servoface.controller.performance import Performance
from servoface.controller.pipeline import FrameTrace
from servoface.controller.script import load_script
from servoface.sim.rig import HeadPose

SCRIPTS_DIR = Path(__file__).resolve().parent / "scripts"
DEMO_SCRIPTS = {"human": SCRIPTS_DIR / "human_performance.toml", "dog": SCRIPTS_DIR / "dog_performance.toml"}


@dataclass(frozen=True)
class DemoOutputs:
    video: Path
    sheet: Path
    report: Path
    clipped_frame: Path | None
    report_data: dict[str, Any]


def settle_error_tick(face: Face, settle_s: float = 0.6) -> dict[int, int]:
    """Hold the last command for ``settle_s``, then |present - goal| per servo (ticks), from the
    positions the head service read on its last frame."""
    face.hold(settle_s)
    if face.driver is None:
        return {}
    svc = face.service
    last = svc.last_trace
    svc.wait_frame(-1 if last is None else last.index)  # one more cycle: positions read after the hold
    snapshot = svc.telemetry()
    if snapshot is None:
        return {}
    goals = face.pipeline.last_goals_tick
    return {sid: abs(int(pos) - int(goals[sid])) for sid, pos in snapshot.positions_tick().items() if sid in goals}


def gated_pose(face: Face, trace: FrameTrace) -> HeadPose:
    """The face the twin sees for the goals actually sent."""
    joint_deg, offsets, targets = face.pipeline.gate.twin_pose(trace.goals_sent)
    return HeadPose(joint_deg=joint_deg, skin_offset_mm=offsets, actuator_targets=targets)


def render_performance(
    face: Face,
    perf: Performance,
    path: Path,
    *,
    fps: float = 20.0,
    size: tuple[int, int] = (360, 300),
    progress: Callable[[int, int], None] | None = None,
) -> int:
    """Target face (left) vs gated face (right) for the played frames, resampled to ``fps``."""
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.images import render_side_by_side
    from servoface.sim.render.video import write_gif, write_mp4

    traces = perf.traces
    if not traces:
        return 0
    times = np.array([t.t_s for t in traces])
    wanted = np.arange(times[0], times[-1] + 1e-9, 1.0 / fps)
    picks = [int(np.searchsorted(times, w, side="right") - 1) for w in wanted]
    renderer = HeadRenderer(*size)
    try:

        def frames() -> Any:
            for i, k in enumerate(picks):
                trace = traces[max(k, 0)]
                target = face.pipeline.face.solve(trace.aus)
                left = renderer.render(face.head, target)
                right = renderer.render(face.head, gated_pose(face, trace))
                label = "gated" if trace.verdict == "accept" else f"gated ({trace.verdict})"
                if progress is not None:
                    progress(i + 1, len(picks))
                t_local = trace.t_s - traces[0].t_s  # service time -> time into the performance
                yield render_side_by_side(left, right, (f"target  t={t_local:5.2f}s", label))

        writer = write_mp4 if path.suffix.lower() == ".mp4" else write_gif
        return writer(frames(), path, fps)
    finally:
        renderer.close()


def write_sheet(face: Face, path: Path, size: tuple[int, int] = (240, 200)) -> list[str]:
    from PIL import Image as PILImage
    from servoface.sim.expressions import load_library
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.clips import library_sheet

    library = load_library(face.head.expressions_path or face.head.face_type)
    with HeadRenderer(*size) as renderer:
        sheet, names = library_sheet(renderer, face.head, library, show_progress=False)
    PILImage.fromarray(sheet).save(path)
    return names


def write_clipped_frame(face: Face, perf: Performance, path: Path) -> Path | None:
    """Target vs gated, side by side, for the most clipped frame of the run (None if nothing clipped)."""
    clipped = [t for t in perf.traces if t.verdict != "accept"]
    if not clipped:
        return None
    from PIL import Image as PILImage
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.images import render_side_by_side

    def gap(t: FrameTrace) -> int:
        return max(abs(t.goals_requested[s] - t.goals_sent[s]) for s in t.goals_sent)

    worst = max(clipped, key=gap)
    with HeadRenderer(480, 400) as renderer:
        left = renderer.render(face.head, face.pipeline.face.solve(worst.aus))
        right = renderer.render(face.head, gated_pose(face, worst))
    PILImage.fromarray(render_side_by_side(left, right, ("target", f"gated: {worst.verdict}"))).save(path)
    return path


def run_demo(
    out_dir: Path,
    *,
    head: str = "human",
    video_format: str = "mp4",
    baud: int = 1_000_000,
    rate_hz: float = 50.0,
    progress: Callable[[str], None] | None = None,
) -> DemoOutputs:
    """Play the built-in performance of ``head`` on the emulated chain and write the outputs."""
    say = progress or (lambda _msg: None)
    out_dir.mkdir(parents=True, exist_ok=True)
    script = load_script(DEMO_SCRIPTS[head])
    t0 = time.perf_counter()
    say(f"opening the {head} head on an emulated chain at {baud} bps (wire time on)")
    with Face.open(head, emulate=True, baud=baud, rate_hz=rate_hz, wire_time=True) as face:
        t_open = time.perf_counter() - t0
        say(f"playing {script.title!r} ({script.end_s:.1f} s at {rate_hz:g} Hz)")
        perf = face.play(script)
        errors = settle_error_tick(face)
        stats = face.driver.bus.stats.copy() if face.driver is not None else None
        transactions = getattr(stats, "transactions", None)
        written = getattr(stats, "bytes_written", None)
    # the service has stopped (eased, torque off, port closed): the twin and the renderer are ours alone now
    say("rendering the twin video, the contact sheet and the most clipped frame")
    video = out_dir / f"twin.{video_format}"
    n_video = render_performance(face, perf, video)
    sheet = out_dir / "sheet.png"
    names = write_sheet(face, sheet)
    clipped_png = write_clipped_frame(face, perf, out_dir / "clipped.png")
    summary = perf.summary()
    loop = summary.get("loop", {})
    report: dict[str, Any] = {
        "head": head,
        "script": str(DEMO_SCRIPTS[head].name),
        "machine": f"{platform.machine()} {os.cpu_count()} cpu, Python {platform.python_version()}",
        "bus": {
            "interface": "emulator (in-process, wire time on)",
            "baud": baud,
            "servos": len(face.head.actuators),
            "transactions": transactions,
            "bytes_written": written,
        },
        "frames": summary["frames"],
        "verdicts": summary["verdicts"],
        "loop": {
            "target_hz": rate_hz,
            "achieved_hz": loop.get("achieved_hz"),
            "late_frames": loop.get("late"),
            "missed_frames": loop.get("missed"),
            "overruns": loop.get("overruns"),
        },
        "median_stage_ms": summary.get("median_stage_ms", {}),
        "max_goal_error_tick": max(errors.values()) if errors else None,
        "goal_error_tick": {str(k): v for k, v in sorted(errors.items())},
        "clip_reasons": _reason_counts(perf),
        "outputs": {
            "video": video.name,
            "video_frames": n_video,
            "sheet": sheet.name,
            "sheet_expressions": names,
            "clipped_frame": clipped_png.name if clipped_png else None,
        },
        "open_s": round(t_open, 3),
    }
    report["wall_s"] = round(time.perf_counter() - t0, 3)
    report_path = out_dir / "report.json"
    report_path.write_text(json.dumps(report, indent=2) + "\n")
    return DemoOutputs(video, sheet, report_path, clipped_png, report)


def _reason_counts(perf: Performance) -> dict[str, int]:
    counts: dict[str, int] = {}
    for trace in perf.traces:
        for check in trace.checks:
            counts[check] = counts.get(check, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: -kv[1]))
