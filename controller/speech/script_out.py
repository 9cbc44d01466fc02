"""A lip-sync plan as an editable TOML timeline script that ``servoface play`` reads: the mouth AUs as
per-AU keys on the ``speech`` track (``channels``, linear between keys, ``holds = false`` so the face track
takes the mouth back when speech ends), the blend rule that speech owns the mouth AUs it names
(``override``), and the audio file beside it."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from servoface.controller.speech.plan import LipSyncPlan
from servoface.controller.speech.visemes import mouth_aus


def _toml_string(text: str) -> str:
    out = text.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + "".join(c if c.isprintable() else f"\\u{ord(c):04x}" for c in out) + '"'


def script_text(
    plan: LipSyncPlan,
    face_type: str,
    *,
    title: str,
    audio: str = "",
    allowed: frozenset[str] | None = None,
    expression: str | None = None,
) -> str:
    """The TOML text of a speech script (optionally an expression held on the face track while it speaks)."""
    channels = plan.channels(face_type, allowed)
    lines = [
        "# Lip sync written by servoface (say / lipsync). Edit freely: each AU's keys are [t_s, value],",
        "# linear in between; the speech track owns these AUs while it plays (blend rule 'override').",
        "",
        "[script]",
        f'face = "{face_type}"',
        f"title = {_toml_string(title[:200])}",
        f"end_s = {max(plan.duration_s, plan.audio_end_s) + 0.2:.3f}",
    ]
    if audio:
        lines += [f"audio = {_toml_string(audio)}", f"audio_start_s = {plan.audio_start_s:.3f}"]
    lines += ["", "[expressions.speech]", "holds = false", "", "[expressions.speech.channels]"]
    for au, keys in channels.items():
        body = ", ".join(f"[{t:.3f}, {v:.4g}]" for t, v in keys)
        lines.append(f"{au} = [{body}]")
    owned = sorted(set(channels) | (mouth_aus(face_type) & (allowed or mouth_aus(face_type))))
    lines += ["", "[blend]", "rules = { " + ", ".join(f'{au} = "override"' for au in owned) + " }", ""]
    if expression:
        lines += ["[[play]]", "at_s = 0.0", 'track = "face"', f"library = {_toml_string(expression)}", ""]
        lines.insert(lines.index("[expressions.speech]"), "")
    lines += ["[[play]]", "at_s = 0.0", 'track = "speech"', 'expression = "speech"', ""]
    return "\n".join(lines)


def write_script(path: str | Path, text: str) -> Path:
    """Write atomically (temp file + rename)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.chmod(tmp, 0o644)  # as a file written in place (mkstemp makes it 0600)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out
