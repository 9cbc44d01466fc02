"""The main job on the embedded default: a head on the emulated chain plays a performance through the
whole pipeline (wire time on); the twin's view is written as a video, the expression library as a contact
sheet, and what happened as ``report.json``.

The built-in heads play their shipped scripts; any other head (a profile folder) plays its expression
library, keeping the expressions it can show at least in part, or, if it can show none, each AU it can
show in turn (`head_performance`). What is drawn by default is the face the servos make (the gated
command posed by the twin); ``show="target"`` draws the muscle model's wish, ``show="both"`` both.
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


def head_performance(
    face: Face,
    *,
    onset_s: float = 0.4,
    apex_s: float = 0.8,
    offset_s: float = 0.5,
    limit: int | None = None,
) -> tuple[Any, float, str]:
    """(timeline, end_s, title) of the generic performance of ``face.head`` (see the module docstring);
    ``limit``: at most this many expressions (or AUs)."""
    from servoface.controller.timeline import Timeline
    from servoface.controller.timeline.barker import Expression
    from servoface.controller.timeline.dfacs import events_clip, parse_events
    from servoface.controller.timeline.library import DEFAULT_DOG_TIMING
    from servoface.sim.achievable import AchievableFace
    from servoface.sim.expressions import load_library
    from servoface.sim.expressiveness import Expressiveness

    head = face.head
    library = {k: v for k, v in load_library(head.expressions_path or head.face_type).items() if k != "neutral"}
    scores = Expressiveness(AchievableFace(head, face.pipeline.calibration, model=face.pipeline.face))
    keep = [s.name for s in scores.expression_scores(library) if not s.cannot_show][:limit]
    timeline = Timeline(head.face_type)
    t = 0.3
    step = onset_s + apex_s + offset_s + 0.3
    if keep:
        for name in keep:
            expr = library[name]
            if head.face_type == "dog":
                tokens = [{"au": au, "value": value} for au, value in expr.events]
                clip = events_clip(parse_events(tokens, field=f"{head.name}.{name}"), DEFAULT_DOG_TIMING, name=name)
            else:
                clip = Expression.envelope(name, expr.apex(), onset_s, apex_s, offset_s).clip()
            timeline.play(clip, at_s=t)
            t += max(step, float(getattr(clip, "duration_s", step)) + 0.3)
        title = f"{head.name}: {len(keep)} of {len(library)} library expressions it can show"
    else:
        aus = [s for s in scores.au_scores() if not s.cannot_show and not s.name.endswith("L")][:limit]
        for s in aus:
            value = -1.0 if s.name.endswith("-") else 1.0
            pose = {s.name.rstrip("-"): value}
            timeline.play(Expression.envelope(s.name, pose, onset_s, apex_s, offset_s).clip(), at_s=t)
            t += step
        title = f"{head.name}: the {len(aus)} AUs it can show, one by one"
    return timeline, t, title


def render_performance(
    face: Face,
    perf: Performance,
    path: Path,
    *,
    fps: float = 20.0,
    size: tuple[int, int] = (360, 300),
    progress: Callable[[int, int], None] | None = None,
    show: str = "achievable",
) -> int:
    """The played frames resampled to ``fps``: the gated face (default: what the servos were sent, posed
    by the twin), the muscle model's target (``show="target"``) or both side by side (``"both"``)."""
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.images import render_side_by_side, with_label
    from servoface.sim.render.video import write_gif, write_mp4

    if show not in ("achievable", "target", "both"):
        raise ValueError(f"show: expected achievable, target or both, got {show!r}")

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
                t_local = trace.t_s - traces[0].t_s  # service time -> time into the performance
                if progress is not None:
                    progress(i + 1, len(picks))
                if show == "target":
                    yield with_label(
                        renderer.render(face.head, face.pipeline.face.solve(trace.aus)), f"target  t={t_local:5.2f}s"
                    )
                    continue
                right = renderer.render(face.head, gated_pose(face, trace))
                label = "servos" if trace.verdict == "accept" else f"servos ({trace.verdict})"
                if show == "achievable":
                    yield with_label(right, f"{label}  t={t_local:5.2f}s")
                    continue
                left = renderer.render(face.head, face.pipeline.face.solve(trace.aus))
                yield render_side_by_side(left, right, (f"target  t={t_local:5.2f}s", label))

        writer = write_mp4 if path.suffix.lower() == ".mp4" else write_gif
        return writer(frames(), path, fps)
    finally:
        renderer.close()


def write_sheet(face: Face, path: Path, size: tuple[int, int] = (240, 200), show: str = "achievable") -> list[str]:
    from servoface.sim.achievable import AchievableFace
    from servoface.sim.expressions import load_library
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.clips import library_sheet
    from servoface.sim.render.images import save_image

    library = load_library(face.head.expressions_path or face.head.face_type)
    twin = None
    if show != "target":
        twin = AchievableFace(face.head, face.pipeline.calibration, model=face.pipeline.face)
    with HeadRenderer(*size) as renderer:
        sheet, names = library_sheet(renderer, face.head, library, show_progress=False, show=show, achievable=twin)
    save_image(sheet, path)  # all or nothing: no truncated sheet after a failure or Ctrl-C
    return names


def write_clipped_frame(face: Face, perf: Performance, path: Path) -> Path | None:
    """Target vs gated, side by side, for the most clipped frame of the run (None if nothing clipped)."""
    clipped = [t for t in perf.traces if t.verdict != "accept"]
    if not clipped:
        return None
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.images import render_side_by_side, save_image

    def gap(t: FrameTrace) -> int:
        return max(abs(t.goals_requested[s] - t.goals_sent[s]) for s in t.goals_sent)

    worst = max(clipped, key=gap)
    with HeadRenderer(480, 400) as renderer:
        left = renderer.render(face.head, face.pipeline.face.solve(worst.aus))
        right = renderer.render(face.head, gated_pose(face, worst))
    save_image(render_side_by_side(left, right, ("target", f"gated: {worst.verdict}")), path)
    return path


def run_demo(
    out_dir: Path,
    *,
    head: str | Path = "human",
    video_format: str = "mp4",
    baud: int = 1_000_000,
    rate_hz: float = 50.0,
    progress: Callable[[str], None] | None = None,
    show: str = "achievable",
) -> DemoOutputs:
    """Play the performance of ``head`` (a built-in name or a profile folder) on the emulated chain and
    write the outputs (see the module docstring)."""
    say = progress or (lambda _msg: None)
    out_dir.mkdir(parents=True, exist_ok=True)
    builtin = isinstance(head, str) and head in DEMO_SCRIPTS
    t0 = time.perf_counter()
    say(f"opening head {str(head)!r} on an emulated chain at {baud} bps (wire time on)")
    with Face.open(head, emulate=True, baud=baud, rate_hz=rate_hz, wire_time=True) as face:
        t_open = time.perf_counter() - t0
        if builtin:
            script: Any = load_script(DEMO_SCRIPTS[str(head)])
            script_name, end_s, title = DEMO_SCRIPTS[str(head)].name, script.end_s, script.title
        else:
            script, end_s, title = head_performance(face)
            script_name = "generic performance (its library)"
        say(f"playing {title!r} ({end_s:.1f} s at {rate_hz:g} Hz)")
        perf = face.play(script) if builtin else face.perform(script, end_s)  # both on the head service
        errors = settle_error_tick(face)
        stats = face.driver.bus.stats.copy() if face.driver is not None else None
        reads = (
            {"positions": face.driver.sentinel_info, "read": face.driver.fast_read_info}
            if face.driver is not None
            else {}
        )
    # the service has stopped (eased, torque off, port closed): the twin and the renderer are ours alone now
    clips = any(t.verdict != "accept" for t in perf.traces)
    say("rendering the twin video, the contact sheet" + (" and the most clipped frame" if clips else ""))
    video = out_dir / f"twin.{video_format}"
    n_video = render_performance(face, perf, video, show=show)
    sheet = out_dir / "sheet.png"
    names = write_sheet(face, sheet, show=show)
    clipped_png = write_clipped_frame(face, perf, out_dir / "clipped.png")
    summary = perf.summary()
    loop = summary.get("loop", {})
    report: dict[str, Any] = {
        "head": face.head.name if not builtin else head,
        "script": str(script_name),
        "title": title,
        "shown": show,
        "machine": f"{platform.machine()} {os.cpu_count()} cpu, Python {platform.python_version()}",
        "bus": {
            "interface": "emulator (in-process, wire time on)",
            "baud": baud,
            "servos": len(face.head.actuators),
            "transactions": getattr(stats, "transactions", None),
            "bytes_written": getattr(stats, "bytes_written", None),
            **reads,  # how positions were read: the position sentinel (or why not), Fast Sync Read (or why not)
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
        "stop": face.stop_report.lines() if face.stop_report is not None else None,  # the safe stop's summary
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
