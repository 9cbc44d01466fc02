"""A twin video of a talking head with its sound: the achievable face (the goals the gate passed, posed by
the twin) frame by frame, H.264, with the speech WAV muxed in as AAC by imageio-ffmpeg's bundled ffmpeg."""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from servoface.controller.speech.audio import write_wav
from servoface.controller.speech.errors import SpeechError

if TYPE_CHECKING:
    from servoface.controller.face import Face
    from servoface.controller.performance import Performance
    from servoface.controller.speech.lipsync import Speech


def render_talking(
    face: Face, perf: Performance, speech: Speech, path: Path, *, fps: float = 25.0, size: tuple[int, int] = (480, 400)
) -> int:
    """Render the played frames (achievable face) at ``fps`` and mux the audio, delayed by the plan's lead."""
    from servoface.controller.demo import gated_pose
    from servoface.sim.render import HeadRenderer
    from servoface.sim.render.video import write_mp4

    traces = perf.traces
    if not traces:
        raise SpeechError("nothing was played: no frames to render")
    times = np.array([t.t_s for t in traces]) - traces[0].t_s
    wanted = np.arange(0.0, times[-1] + 1e-9, 1.0 / fps)
    picks = [max(int(np.searchsorted(times, w, side="right") - 1), 0) for w in wanted]
    renderer = HeadRenderer(*size)
    with tempfile.TemporaryDirectory(prefix="servoface-say-") as tmp:
        silent = Path(tmp) / "video.mp4"
        try:
            count = write_mp4((renderer.render(face.head, gated_pose(face, traces[k])) for k in picks), silent, fps)
        finally:
            renderer.close()
        pad = np.zeros(int(round(speech.plan.audio_start_s * speech.rate_hz)))
        audio = np.concatenate([pad, speech.samples])
        wav = write_wav(Path(tmp) / "audio.wav", (np.clip(audio, -1, 1) * 32767).astype(np.int16), speech.rate_hz)
        mux(silent, wav, path)
    return count


def mux(video: Path, audio: Path, out: Path) -> Path:
    """Copy the video stream, add the audio as AAC; the result lasts as long as the longer of the two."""
    import imageio_ffmpeg

    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [
        imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error", "-i", str(video), "-i", str(audio),
        "-map", "0:v:0", "-map", "1:a:0", "-c:v", "copy", "-c:a", "aac", "-b:a", "96k", str(out),
    ]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if proc.returncode != 0:
        raise SpeechError(f"{out}: ffmpeg could not mux the audio: {proc.stderr.strip()[:300]}")
    return out
