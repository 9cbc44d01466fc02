"""Animations: the easing of a neutral -> apex -> neutral clip, and GIF / MP4 writers.

GIF goes through Pillow (adaptive palette per frame, loops forever); MP4 through imageio-ffmpeg, whose
wheel ships its own ffmpeg binary, so no system ffmpeg is needed. Both take any iterable of equally sized
(H, W, 3) uint8 frames and return the number of frames written. Both write all or nothing
(`servoface.sim.render.atomic`): a frame that fails, or Ctrl-C, leaves no truncated file at the target.
"""

from __future__ import annotations

import contextlib
import errno
import re
import subprocess
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image as PILImage
from servoface.sim.render.atomic import atomic_output

Image = NDArray[np.uint8]

# a there-and-back clip: hold neutral, ease in, hold the apex, ease out, hold neutral (fractions of the clip)
PHASES = (("hold", 0.10), ("in", 0.30), ("hold_apex", 0.20), ("out", 0.30), ("hold", 0.10))


def smoothstep(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Ease in and out (C1: zero speed at both ends), x in 0..1."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def there_and_back(duration_s: float = 2.0, fps: float = 20.0) -> NDArray[np.float64]:
    """Weights 0..1 per frame for neutral -> apex -> neutral with smooth easing (first and last are 0)."""
    if not (np.isfinite(duration_s) and 0.2 <= duration_s <= 60.0):
        raise ValueError(f"duration_s must be 0.2..60 s, got {duration_s}")
    if not (np.isfinite(fps) and 1.0 <= fps <= 120.0):
        raise ValueError(f"fps must be 1..120, got {fps}")
    n = max(3, round(duration_s * fps))
    t = np.linspace(0.0, 1.0, n)
    edges = np.cumsum([0.0] + [f for _, f in PHASES])
    w = np.zeros(n)
    for (kind, _), lo, hi in zip(PHASES, edges[:-1], edges[1:], strict=True):
        inside = (t >= lo) & (t <= hi)
        local = (t[inside] - lo) / (hi - lo)
        if kind == "in":
            w[inside] = smoothstep(local)
        elif kind == "out":
            w[inside] = 1.0 - smoothstep(local)
        elif kind == "hold_apex":
            w[inside] = 1.0
    return w


def _frame(img: Image, index: int, shape: tuple[int, ...] | None) -> Image:
    arr = np.asarray(img)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.dtype != np.uint8:
        raise ValueError(f"frame {index}: expected (H, W, 3) uint8, got {arr.shape} {arr.dtype}")
    if shape is not None and arr.shape != shape:
        raise ValueError(f"frame {index}: size {arr.shape[:2]} differs from the first frame's {shape[:2]}")
    return arr


def _check_fps(fps: float) -> None:
    if not (np.isfinite(fps) and 1.0 <= fps <= 120.0):
        raise ValueError(f"fps must be 1..120, got {fps}")


def write_gif(frames: Iterable[Image], path: str | Path, fps: float = 20.0) -> int:
    """Write an endlessly looping GIF; returns the number of frames given.

    All frames share one 256-colour palette (median cut over a sample of the frames): no palette flicker
    between frames and ~30x faster than quantising each frame on its own. Identical consecutive frames
    (holds) may be stored once with their durations added; the total duration is frames / fps.
    """
    _check_fps(fps)
    with atomic_output(path) as tmp:  # before any frame: a bad target fails at once
        arrays: list[Image] = []
        shape: tuple[int, ...] | None = None
        for i, img in enumerate(frames):
            arr = _frame(img, i, shape)
            shape = arr.shape
            arrays.append(arr)
        if not arrays:
            raise ValueError(f"{path}: no frames to write")
        step = max(1, len(arrays) // 8)
        sample = np.concatenate([a[::2, ::2] for a in arrays[::step]] + [arrays[-1][::2, ::2]])
        palette = PILImage.fromarray(sample).quantize(colors=256, method=PILImage.Quantize.MEDIANCUT)
        images = [PILImage.fromarray(a).quantize(palette=palette, dither=PILImage.Dither.NONE) for a in arrays]
        images[0].save(
            tmp,  # keeps the target's suffix: Pillow picks the format by it, as it did from the target
            save_all=True,
            append_images=images[1:],
            duration=round(1000.0 / fps),
            loop=0,
            optimize=False,
            disposal=1,
        )
    return len(images)


def write_mp4(frames: Iterable[Image], path: str | Path, fps: float = 20.0) -> int:
    """Write an H.264 MP4 (yuv420p, plays everywhere); odd sizes are padded by one pixel. Returns frames."""
    import imageio.v2 as imageio

    _check_fps(fps)
    count = 0
    shape: tuple[int, ...] | None = None
    with atomic_output(path) as tmp:
        writer = None
        try:
            for i, img in enumerate(frames):
                arr = _frame(img, i, shape)
                shape = arr.shape
                h, w = arr.shape[:2]
                if h % 2 or w % 2:  # yuv420p needs even sides
                    arr = np.pad(arr, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
                if writer is None:
                    writer = imageio.get_writer(
                        str(tmp),  # keeps the target's suffix: ffmpeg picks the container by it
                        format="FFMPEG",
                        mode="I",
                        fps=fps,
                        codec="libx264",
                        quality=7,
                        pixelformat="yuv420p",
                        macro_block_size=1,
                        ffmpeg_log_level="error",
                    )
                writer.append_data(arr)
                count += 1
        except BaseException:
            if writer is not None:  # stop ffmpeg; the error that got us here is the one to report
                with contextlib.suppress(Exception):
                    writer.close()
            raise
        if writer is None:
            raise ValueError(f"{path}: no frames to write")
        writer.close()
        encoded = _encoded_frames(tmp)
        if encoded != count:  # imageio-ffmpeg does not report how ffmpeg exited: read back what it wrote
            found = "an unreadable file" if encoded is None else f"{encoded} frames"
            raise OSError(
                errno.EIO,
                f"ffmpeg did not finish the video ({count} frames given, {found} written; a full disk or a file "
                "size limit is the usual cause)",
                str(path),
            )
    return count


def _encoded_frames(path: str | Path) -> int | None:
    """Frames in the video stream of an MP4, counted by ffmpeg copying the stream (no decoding, so fast);
    None if ffmpeg cannot read the file (e.g. no index: the encoder did not finish it)."""
    import imageio_ffmpeg

    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-nostdin", "-i", str(path)]
    cmd += ["-map", "0:v:0", "-c", "copy", "-f", "null", "-"]
    run = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, check=False)
    found = re.findall(rb"frame=\s*(\d+)", run.stderr)
    if run.returncode != 0 or not found:
        return None
    return int(found[-1])


WRITERS = {".gif": write_gif, ".mp4": write_mp4}
