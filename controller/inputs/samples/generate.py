"""Write the small synthetic sample files in this folder (deterministic; no tracker, no downloads).

    python -m servoface.controller.inputs.samples.generate [FOLDER]   # default: this folder

- ``openface_smile.csv``: OpenFace 2.x FeatureExtraction layout (leading spaces in the header, gaze/pose
  columns, AUxx_r and AUxx_c), 30 fps, 2 s: a smile (AU6 + AU12) rises and falls; tracking is lost
  (success = 0) for 5 frames in the middle.
- ``pyfeat_surprise.csv``: py-feat columns (frame, FaceScore, AU01..AU43), 30 fps, 1 s surprise; one
  row without a face (empty AUs).
- ``arkit_smile.jsonl``: one message per line (controller/inputs/messages.py), 30 fps, 2 s: smile
  blendshapes, a head turn to the subject's own left and a look to the right.
- ``mediapipe_blink.csv``: blendshape columns + time + head yaw, 30 fps, 1 s, one blink.
- ``greeting.fap``: an MPEG-4 FAP file (fap.py): 25 fps, 1 s, jaw open + smile corners + brows.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

HERE = Path(__file__).parent
OPENFACE_AUS = (
    "01",
    "02",
    "04",
    "05",
    "06",
    "07",
    "09",
    "10",
    "12",
    "14",
    "15",
    "17",
    "20",
    "23",
    "25",
    "26",
    "45",
)
PYFEAT_AUS = (
    "01",
    "02",
    "04",
    "05",
    "06",
    "07",
    "09",
    "10",
    "11",
    "12",
    "14",
    "15",
    "17",
    "20",
    "23",
    "24",
    "25",
    "26",
    "28",
    "43",
)


def bump(t: float, start: float, end: float) -> float:
    """0 outside [start, end], a raised-cosine bump of height 1 inside."""
    if not start < t < end:
        return 0.0
    return 0.5 - 0.5 * math.cos(2 * math.pi * (t - start) / (end - start))


def openface(path: Path) -> None:
    header = ["frame", "face_id", "timestamp", "confidence", "success"]
    header += [f"gaze_0_{a}" for a in "xyz"] + ["gaze_angle_x", "gaze_angle_y"]
    header += ["pose_Tx", "pose_Ty", "pose_Tz", "pose_Rx", "pose_Ry", "pose_Rz"]
    header += [f"AU{n}_r" for n in OPENFACE_AUS] + [f"AU{n}_c" for n in OPENFACE_AUS] + ["AU28_c"]
    lines = [", ".join(header)]
    for i in range(60):
        t = i / 30.0
        lost = 28 <= i < 33
        smile = 3.5 * bump(t, 0.2, 1.8)  # a broad smile on OpenFace's 0..5 scale
        r = {n: 0.0 for n in OPENFACE_AUS}
        r["12"], r["06"], r["25"] = smile, 0.6 * smile, 0.3 * smile
        row = [str(i + 1), "0", f"{t:.3f}", "0.20" if lost else "0.98", "0" if lost else "1"]
        row += ["0.05", "0.10", "-0.99", "0.05", "0.10", "10.0", "-5.0", "500.0", "0.02", "0.05", "0.01"]
        row += [f"{r[n]:.2f}" for n in OPENFACE_AUS] + [str(int(r[n] > 1.0)) for n in OPENFACE_AUS] + ["0"]
        lines.append(", ".join(row))
    path.write_text("\n".join(lines) + "\n")


def pyfeat(path: Path) -> None:
    lines = [",".join(["frame", "FaceScore"] + [f"AU{n}" for n in PYFEAT_AUS])]
    for i in range(30):
        t = i / 30.0
        s = bump(t, 0.0, 1.0)
        values = {n: 0.05 for n in PYFEAT_AUS}
        values.update({"01": s, "02": s, "05": 0.5 * s, "26": 0.8 * s})
        if i == 15:
            lines.append(",".join([str(i), ""] + [""] * len(PYFEAT_AUS)))
            continue
        lines.append(",".join([str(i), "0.99"] + [f"{values[n]:.3f}" for n in PYFEAT_AUS]))
    path.write_text("\n".join(lines) + "\n")


def arkit(path: Path) -> None:
    lines = []
    for i in range(60):
        t = i / 30.0
        s = bump(t, 0.1, 1.9)
        msg = {
            "t": round(t, 4),
            "blendshapes": {
                "mouthSmileLeft": round(0.9 * s, 4),
                "mouthSmileRight": round(0.8 * s, 4),
                "cheekSquintLeft": round(0.5 * s, 4),
                "cheekSquintRight": round(0.5 * s, 4),
                "jawOpen": round(0.2 * s, 4),
                "eyeLookOutRight": round(0.4 * s, 4),
                "eyeLookInLeft": round(0.4 * s, 4),
            },
            "head": {"yaw_deg": round(15.0 * s, 3), "pitch_deg": round(-5.0 * s, 3), "roll_deg": 0.0},
            "confidence": 0.95,
        }
        lines.append(json.dumps(msg))
    path.write_text("\n".join(lines) + "\n")


def mediapipe(path: Path) -> None:
    shapes = ("eyeBlinkLeft", "eyeBlinkRight", "browInnerUp", "mouthSmileLeft", "mouthSmileRight", "jawOpen")
    lines = [",".join(["t"] + list(shapes) + ["yaw_deg"])]
    for i in range(30):
        t = i / 30.0
        blink = bump(t, 0.4, 0.6)
        row = [
            f"{t:.4f}",
            f"{blink:.3f}",
            f"{blink:.3f}",
            "0.100",
            "0.300",
            "0.300",
            "0.050",
            f"{-10 * t:.2f}",
        ]
        lines.append(",".join(row))
    path.write_text("\n".join(lines) + "\n")


def fap(path: Path) -> None:
    # header: "# comment", then "<version> <name> <fps> <n_frames>", then per frame a mask line of 68
    # 0/1 and a line with the values of the set FAPs (MPEG-4 FBA text format, see fap.py)
    used = {
        3: "open_jaw",
        4: "lower_t_midlip",
        12: "raise_l_cornerlip",
        13: "raise_r_cornerlip",
        31: "raise_l_i_eyebrow",
        32: "raise_r_i_eyebrow",
    }
    lines = ["# servoface sample: jaw open, smile corners, inner brows up", "2.1 greeting 25 25"]
    for i in range(25):
        s = bump(i / 25.0, 0.0, 1.0)
        mask = ["1" if n in used else "0" for n in range(1, 69)]
        values = {3: 400 * s, 4: -100 * s, 12: 150 * s, 13: 150 * s, 31: 120 * s, 32: 120 * s}
        lines.append(" ".join(mask))
        lines.append(" ".join([str(i)] + [str(round(values[n])) for n in sorted(used)]))
    path.write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> None:
    """Write the samples into the folder given (created if need be), else into this one (the repo's)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) > 1:
        raise SystemExit("usage: python -m servoface.controller.inputs.samples.generate [FOLDER]")
    out = Path(args[0]) if args else HERE
    out.mkdir(parents=True, exist_ok=True)
    openface(out / "openface_smile.csv")
    pyfeat(out / "pyfeat_surprise.csv")
    arkit(out / "arkit_smile.jsonl")
    mediapipe(out / "mediapipe_blink.csv")
    fap(out / "greeting.fap")


if __name__ == "__main__":
    main()
