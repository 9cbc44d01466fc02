"""`servoface bench face`: the muscle model's time per frame and the renderer's frames per second.

Muscle model: median of ``servoface.sim.face_model.benchmark_solve`` (AU frame -> posed head), per built-in head;
goal <= 1 ms for the human head. Rendering: frames per second at 640x480 of each head posed through a
cycle of expression poses (solved beforehand, so only posing the meshes and drawing are timed); one
renderer, reused, as the twin preview uses it. Goal >= 30 fps on 2 CPU cores (Mesa llvmpipe, no GPU).
Twin fidelity: the largest landmark distance between the muscle model's target face and the face the
servos make (targets -> goal ticks -> the twin's ``pose_from_targets``), over every library expression
and every single AU at +1 (and -1 where it has a counter), per built-in head; goal <= 1 mm. The landmark
set is ``servoface.sim.landmarks`` (profile points, anchor vertices, lid margins, pupils, ear and tongue
tips).
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Iterator

from servoface.controller.benchmarks.figure import Figure

HEADS = ("human", "dog")
RENDER_SIZE = (640, 480)


def _solve_figures(quick: bool) -> Iterator[Figure]:
    from servoface.sim.face_model import benchmark_solve

    for name in HEADS:
        times_s = benchmark_solve(name, 50 if quick else 500)
        yield Figure(
            f"muscle_model_solve_median_{name}",
            statistics.median(times_s) * 1000.0,
            "ms",
            limit=1.0,
            better="lower",
            note=f"FaceModel.solve, AU frame -> HeadPose, median of {len(times_s)} varied frames",
        )


def _fidelity_figures() -> Iterator[Figure]:
    from servoface.sim.heads import load_head
    from servoface.sim.landmarks import landmark_set, library_fidelity

    for name in HEADS:
        cases = library_fidelity(name)
        worst = max(cases, key=lambda c: c.max_error_mm)
        yield Figure(
            f"twin_fidelity_max_landmark_error_{name}",
            worst.max_error_mm,
            "mm",
            limit=1.0,
            better="lower",
            note=f"max over {len(cases)} cases (library apexes, single AUs at +-1) and "
            f"{len(landmark_set(load_head(name)))} landmarks; worst {worst.case} at {worst.landmark}",
        )


def _render_figures(quick: bool) -> Iterator[Figure]:
    from servoface.sim.expressions import load_library
    from servoface.sim.heads import load_head
    from servoface.sim.render.clips import apex_aus
    from servoface.sim.render.renderer import HeadRenderer
    from servoface.sim.render.twin import face_model

    width, height = RENDER_SIZE
    n_frames = 20 if quick else 120
    t0 = time.perf_counter()
    renderer = HeadRenderer(width, height)
    context_s = time.perf_counter() - t0
    try:
        for name in HEADS:
            head = load_head(name)
            model = face_model(head)
            apexes = [apex_aus(e) for e in load_library(head.face_type).values()] or [{}]
            poses = []
            for i in range(n_frames):
                scale = 0.5 + 0.5 * math.sin(i * 0.3)
                poses.append(model.solve({k: v * scale for k, v in apexes[i % len(apexes)].items()}))
            for pose in poses[:3]:  # first frames upload meshes and compile shaders
                renderer.render(head, pose)
            frame_s = []
            cpu_start = time.process_time()
            for pose in poses:
                t0 = time.perf_counter()
                renderer.render(head, pose)
                frame_s.append(time.perf_counter() - t0)
            cpu_s = time.process_time() - cpu_start
            yield Figure(
                f"render_fps_{name}_{width}x{height}",
                1.0 / statistics.median(frame_s),
                "fps",
                limit=30.0,
                goal=30.0,
                better="higher",
                note=f"1 / median wall time of {n_frames} posed frames (skinning, normals, draw, readback); "
                f"mean {n_frames / sum(frame_s):.1f} fps; EGL llvmpipe",
            )
            yield Figure(
                f"render_cpu_per_frame_{name}_{width}x{height}",
                cpu_s / n_frames * 1000.0,
                "ms",
                limit=1000.0 / 30.0,
                better="lower",
                note="CPU time of all our threads (Python + llvmpipe) per frame; steadier under load",
            )
    finally:
        renderer.close()
    yield Figure("render_context_creation", context_s * 1000.0, "ms", note="EGL context + pyrender renderer, once")


def run(quick: bool = False) -> Iterator[Figure]:
    yield from _solve_figures(quick)
    yield from _fidelity_figures()
    yield from _render_figures(quick)
