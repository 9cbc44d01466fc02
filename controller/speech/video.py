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
    times = np.array([t.t_s for t in traces])  # the mouth clock: 0 = the speech track's start
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
    from servoface.sim.render.atomic import atomic_output

    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(out) as partial:  # all or nothing: an interrupted mux leaves no truncated video
        _mux_to(video, audio, partial, out)
    return out


def _mux_to(video: Path, audio: Path, partial: Path, out: Path) -> None:
    """`mux` into ``partial`` (renamed onto ``out`` by the caller once ffmpeg succeeded)."""
    import imageio_ffmpeg

    cmd = [
        imageio_ffmpeg.get_ffmpeg_exe(),
        "-y",
        "-loglevel",
        "error",
        "-i",
        str(video),
        "-i",
        str(audio),
        "-map",
        "0:v:0",
        "-map",
        "1:a:0",
        "-c:v",
        "copy",
        "-c:a",
        "aac",
        "-b:a",
        "96k",
        str(partial),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if proc.returncode != 0:
        raise SpeechError(f"{out}: ffmpeg could not mux the audio: {proc.stderr.strip()[:300]}")


def plot_timing(face: Face, perf: Performance, speech: Speech, path: Path, *, latency_s: float = 0.0) -> Path:
    """The sound's waveform against the jaw: the jaw's goal per frame (ticks, as sent) and the plan's
    jaw opening, on one time axis (the audio clock), with the viseme onsets marked — to check the timing
    by eye."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    jaw = face.head.servo_ids.get("jaw")
    traces = perf.traces
    t0 = 0.0  # the frames' times are on the mouth clock already (0 = the speech track's start)
    shift = speech.plan.audio_start_s + latency_s  # mouth clock -> audio clock
    fig, (ax_audio, ax_jaw) = plt.subplots(2, 1, figsize=(10, 4.2), sharex=True)
    t_audio = np.arange(len(speech.samples)) / speech.rate_hz
    ax_audio.plot(t_audio, speech.samples, lw=0.4, color="#345")
    ax_audio.set_ylabel("audio")
    for seg in speech.plan.segments:
        if seg.viseme != "sil":
            ax_audio.axvline(seg.start_s, color="#c63", lw=0.4, alpha=0.5)
            ax_audio.text(seg.start_s, 0.9 * float(np.max(np.abs(speech.samples)) or 1), seg.viseme, fontsize=6)
    ax_jaw.plot(
        speech.plan.times_s - speech.plan.audio_start_s,
        speech.plan.feature("open"),
        color="#888",
        lw=1,
        label="plan: jaw opening (0..1)",
    )
    ax_jaw.set_ylabel("opening")
    if jaw is not None and traces:
        ticks = np.array([t.goals_sent[jaw] for t in traces], dtype=float)
        span = float(np.ptp(ticks)) or 1.0
        times = np.array([t.t_s - t0 for t in traces]) - shift + latency_s
        ax_jaw.step(
            times,
            (ticks - ticks.min()) / span,
            where="post",
            color="#17a",
            lw=1,
            label=f"jaw goal sent (servo {jaw}, scaled)",
        )
    ax_jaw.set_xlabel("audio time (s)")
    ax_jaw.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
