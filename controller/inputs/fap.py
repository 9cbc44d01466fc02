"""MPEG-4 FAP files (face animation parameters, ISO/IEC 14496-2) -> a human Recording, via a small mapping.

File format (the MPEG-4 FBA text ``.fap``): ``#`` comment lines; a header ``<version> <name> <fps>
<n_frames>`` (the name may contain spaces: fps and count are the last two fields); then per frame a MASK
line of 68 ``0``/``1`` (FAP 1..68 present; Greta writes 69, FAPs 0..68) and a VALUES line
``<frame number> <value of each present FAP, in FAP order>``. Values are integers in FAP units (FAPU):
distances in fractions of the neutral face's own distances (MNS = mouth-nose separation / 1024, MW = mouth
width / 1024, ENS = eye-nose separation / 1024, ES = eye separation / 1024, IRISD = iris diameter / 1024)
and angles in AU = 1e-5 rad (muscle-models.md §7). Unused FAPs are ignored; FAP 1/2 (viseme, expression)
are not mapped.

Mapping [project]: FAPs are relative to the face's own size, so one full scale per FAP turns a value into
an AU intensity, ``AU = clamp(sign * value / full_scale)``. Full scales are chosen so a clearly visible
action reads as 1 (e.g. a 256 MNS corner raise = a quarter of the mouth-nose distance = a full smile).
Jaw opening goes through the blendshape ``jawOpen`` ramps (AU25/26/27) with 1024 MNS = fully open. Angles
become degrees for the eye and head AUs (head_pose.py / blendshapes.gaze_aus scales). Signs follow the FAP
table as transcribed here (flagged like the sheet: check ISO/IEC 14496-2): ``l``/``r`` = the face's own
side; open_jaw, lower_t_midlip, close_*_eyelid, head_pitch, pitch_*_eyeball + = down; raise_* and lift_*
+ = up; stretch_* + = outwards; squeeze_* + = towards the midline; yaw + = to the face's left; head_roll
+ = to the face's right.
"""

from __future__ import annotations

import math
from pathlib import Path

from servoface.controller.inputs.assemble import RawRow, ReadOptions, assemble
from servoface.controller.inputs.blendshapes import load_blendshape_map
from servoface.controller.inputs.csv_table import read_text
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.head_pose import eye_angles_aus, head_pose_aus
from servoface.controller.inputs.recorded import Recording
from servoface.controller.inputs.report import InputReport
from servoface.controller.inputs.tolerance import BadRow, Tolerance

N_FAPS = 68
FAPU_ANGLE_RAD = 1e-5

#: FAP number -> (AU, sign, full scale in FAPU). Several FAPs on one AU combine by max.
FAP_TO_AU: dict[int, tuple[str, float, float]] = {
    5: ("AU17", 1.0, 256.0),  # raise_b_midlip (MNS, up): chin raiser pushes the lower lip up
    6: ("AU20L", 1.0, 256.0),  # stretch_l_cornerlip (MW, outwards)
    7: ("AU20R", 1.0, 256.0),
    12: ("AU12L", 1.0, 256.0),  # raise_l_cornerlip (MNS, up)
    13: ("AU12R", 1.0, 256.0),
    16: ("AU18", 1.0, 256.0),  # push_b_lip (MNS, forwards): pucker
    17: ("AU18", 1.0, 256.0),  # push_t_lip
    19: ("AU43L", 1.0, 1024.0),  # close_t_l_eyelid (IRISD, down): 1024 IRISD = lid over the whole iris
    20: ("AU43R", 1.0, 1024.0),
    31: ("AU1L", 1.0, 256.0),  # raise_l_i_eyebrow (ENS, up)
    32: ("AU1R", 1.0, 256.0),
    35: ("AU2L", 1.0, 256.0),  # raise_l_o_eyebrow (ENS, up)
    36: ("AU2R", 1.0, 256.0),
    37: ("AU4L", 1.0, 128.0),  # squeeze_l_eyebrow (ES, towards the midline)
    38: ("AU4R", 1.0, 128.0),
    39: ("AU34", 1.0, 256.0),  # puff_l_cheek (ES)
    40: ("AU34", 1.0, 256.0),
    41: ("AU6L", 1.0, 256.0),  # lift_l_cheek (ENS, up)
    42: ("AU6R", 1.0, 256.0),
    61: ("AU38L", 1.0, 128.0),  # stretch_l_nose (ENS, outwards): nostril dilated [project full scale]
    62: ("AU38R", 1.0, 128.0),  # stretch_r_nose
    63: ("AU9", 1.0, 256.0),  # raise_nose (ENS, up)
}
#: Bidirectional FAPs whose NEGATIVE side is another AU: FAP -> (AU for value < 0, full scale).
FAP_NEGATIVE: dict[int, tuple[str, float]] = {
    4: ("AU10", 256.0),  # lower_t_midlip < 0: upper lip raised
    12: ("AU15L", 256.0),  # raise_l_cornerlip < 0: corner down
    13: ("AU15R", 256.0),
    19: ("AU5L", 512.0),  # close_t_l_eyelid < 0: lid opened wider
    20: ("AU5R", 512.0),
    31: ("AU4L", 256.0),  # raise_l_i_eyebrow < 0: brow lowered
    32: ("AU4R", 256.0),
    61: ("AU39L", 128.0),  # stretch_l_nose < 0: nostril compressed
    62: ("AU39R", 128.0),
}
OPEN_JAW_FULL_MNS = 1024.0


def _clamp01(x: float) -> float:
    return min(1.0, max(0.0, x))


def fap_to_aus(faps: dict[int, float]) -> dict[str, float]:
    """One frame's FAP values (number -> FAPU) -> human AUs 0..1 (see the module doc)."""
    out: dict[str, float] = {}

    def put(au: str, value: float) -> None:
        out[au] = max(out.get(au, 0.0), _clamp01(value))

    for number, value in faps.items():
        if number in FAP_TO_AU:
            au, sign, full = FAP_TO_AU[number]
            if sign * value > 0:
                put(au, sign * value / full)
        if number in FAP_NEGATIVE and value < 0:
            au, full = FAP_NEGATIVE[number]
            put(au, -value / full)
    if 3 in faps:
        jaw = load_blendshape_map().to_aus({"jawOpen": _clamp01(faps[3] / OPEN_JAW_FULL_MNS)})
        for au, value in jaw.items():
            put(au, value)
    deg = math.degrees(FAPU_ANGLE_RAD)
    if {48, 49, 50} & set(faps):
        aus = head_pose_aus(faps.get(49, 0.0) * deg, -faps.get(48, 0.0) * deg, -faps.get(50, 0.0) * deg)
        out.update(aus)
    if {23, 24, 25, 26} & set(faps):
        yaw_deg = (faps.get(23, 0.0) + faps.get(24, 0.0)) / 2 * deg
        pitch_deg = -(faps.get(25, 0.0) + faps.get(26, 0.0)) / 2 * deg
        out.update(eye_angles_aus(yaw_deg, pitch_deg))
    return out


def _header(header: str, where: str) -> tuple[str, float, int]:
    """``<version> <name, may contain spaces> <fps> <n_frames>`` -> (name, fps, n_frames)."""
    parts = header.split()
    try:
        if len(parts) < 4:
            raise ValueError(header)
        float(parts[0])
        return " ".join(parts[1:-2]), float(parts[-2]), int(float(parts[-1]))
    except (ValueError, OverflowError) as err:  # OverflowError: a frame count of 1e400 (inf) as an int
        raise InputError(f"{where}: expected '<version> <name> <fps> <n_frames>', got {header[:80]!r}") from err


def read_fap(
    path: str | Path,
    *,
    options: ReadOptions | None = None,
    mirror: bool | None = None,
    fps: float | None = None,
    interpolate: bool | None = None,
) -> Recording:
    """Read an MPEG-4 ``.fap`` file into a human Recording (``fps`` overrides the header's). Mask lines of 68
    values are FAPs 1..68; Greta writes 69 (FAPs 0..68, FAP 0 unused): both are read."""
    from servoface.controller.inputs.openface import _options

    opts = _options(options, mirror=mirror, fps=fps, interpolate=interpolate)
    file = Path(path)
    report = InputReport(str(file), reader="MPEG-4 FAP")
    tol = Tolerance(report, opts.bad_rows)
    raw_lines = read_text(file).splitlines()
    lines = [
        (i, ln.strip()) for i, ln in enumerate(raw_lines, start=1) if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not lines:
        raise InputError(f"{file}: empty, expected a header '<version> <name> <fps> <n_frames>'")
    line_no, header = lines[0]
    name, header_fps, n_frames = _header(header, f"{file}: line {line_no}")
    rate = opts.fps if opts.fps is not None else header_fps
    if not (math.isfinite(rate) and 0 < rate <= 10_000):
        raise InputError(f"{file}: line {line_no}: fps {rate!r} is not within 0..10000")
    body = lines[1:]
    if len(body) % 2:
        if len(body) > 2:
            report.skip("a mask line without its values line at the end")
            body = body[:-1]
        else:
            raise InputError(f"{file}: line {body[-1][0]}: a mask line without its values line")
    rows: list[RawRow] = []
    widths: set[int] = set()
    for k in range(0, len(body), 2):
        (mask_no, mask_text), (val_no, val_text) = body[k], body[k + 1]
        try:
            rows.append(_frame(file, mask_no, mask_text, val_no, val_text, widths))
        except BadRow as err:
            tol.handle(err)
    if 69 in widths:
        report.notes.append("69-value masks (FAPs 0..68, Greta): FAP 0 ignored")
    if name:
        report.notes.append(f"animation {name!r}, header {header_fps:g} fps")
    if n_frames != len(rows) + tol.bad:
        report.notes.append(f"header says {n_frames} frames, the file has {len(rows) + tol.bad}")
    opts = _options(opts, fps=rate, time_unit="frames" if opts.time_unit == "auto" else None)
    return assemble(
        rows, report, opts, tol, kind="aus", time_column="frame", default_fps=rate, total_rows=len(body) // 2
    )


def _frame(file: Path, mask_no: int, mask_text: str, val_no: int, val_text: str, widths: set[int]) -> RawRow:
    mask = mask_text.split()
    if len(mask) not in (N_FAPS, N_FAPS + 1) or any(m not in ("0", "1") for m in mask):
        raise BadRow(
            f"{file}: line {mask_no}: expected a mask of {N_FAPS} (or Greta's {N_FAPS + 1}) 0/1 values, "
            f"got {len(mask)} items",
            "bad mask lines",
        )
    widths.add(len(mask))
    first = 1 if len(mask) == N_FAPS else 0
    present = [n for n, m in enumerate(mask, start=first) if m == "1"]
    values = val_text.split()
    if len(values) == len(present) and first == 0 and mask[0] == "1":
        present = present[1:]  # Greta: FAP 0's slot holds the frame number
    if len(values) != len(present) + 1:
        raise BadRow(
            f"{file}: line {val_no}: expected the frame number and {len(present)} values "
            f"(one per FAP set in the mask), got {len(values)} items",
            "values lines that do not match their mask",
        )
    numbers: list[float] = []
    for column, text in enumerate(values, start=1):
        try:
            number = float(text)
        except ValueError as err:
            raise BadRow(f"{file}: line {val_no}, column {column}: {text!r} is not a number", "text in values") from err
        if not math.isfinite(number):
            raise BadRow(f"{file}: line {val_no}, column {column}: {text!r} is not finite", "non-finite values")
        numbers.append(number)
    faps = {n: v for n, v in zip(present, numbers[1:], strict=True) if n >= 1}
    return RawRow(val_no, numbers[0], fap_to_aus(faps))
