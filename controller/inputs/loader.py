"""Pick the reader of a recorded file by what is in it, not by its name (an OpenFace file saved as
``.openface`` or ``.txt``, a tab-separated ``.tsv``, a MediaPipe dump named ``.json``):

* first non-blank line starts with ``{`` or ``[`` -> JSON (lines, pretty-printed objects or one array; messages
  or MediaPipe results);
* ``.fap``, or a header ``<version> <name> <fps> <n>`` followed by a 68/69-value 0/1 mask -> MPEG-4 FAP;
* otherwise a delimited table, by its header (separator sniffed): ``AUxx_r`` -> OpenFace, ``AUxx`` ->
  py-feat, ARKit/MediaPipe names -> blendshapes; none of these -> an error saying what was found.
"""

from __future__ import annotations

import re
from pathlib import Path

from servoface.controller.inputs.assemble import ReadOptions
from servoface.controller.inputs.csv_table import read_text, sniff_delimiter
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.recorded import Recording
from servoface.sim.rig import FaceType

_MASK = re.compile(r"^[01](\s+[01]){67,68}\s*$")


def detect_format(file: Path) -> str:
    """``"jsonl"``, ``"fap"``, ``"openface"``, ``"pyfeat"`` or ``"blendshapes"`` (InputError otherwise)."""
    lines = [ln.strip() for ln in read_text(file).splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{file}: empty file, expected a tracker recording")
    first = lines[0]
    if first.startswith(("{", "[")):
        return "jsonl"
    if file.suffix.lower() == ".fap" or (len(lines) > 1 and _MASK.match(lines[1])):
        return "fap"
    delimiter = sniff_delimiter(first)
    header = [h.strip().strip('"') for h in first.split(delimiter)]
    if any(re.fullmatch(r"AU\d{2}_r", h) for h in header):
        return "openface"
    if any(re.fullmatch(r"AU\d{2}", h) for h in header):
        return "pyfeat"
    from servoface.controller.inputs.blendshapes import load_blendshape_map

    bmap = load_blendshape_map()
    names = 0
    for h in header:
        try:
            bmap.resolve(h, field=h)
            names += 1
        except InputError:
            pass
    if names:
        return "blendshapes"
    shown = ", ".join(h[:24] for h in header[:8])
    raise InputError(
        f"{file}: cannot tell which tracker wrote this; the first line has {shown}. Expected OpenFace "
        "(AU12_r ...), py-feat (AU12 ...), ARKit/MediaPipe blendshape columns, JSON lines or an MPEG-4 .fap"
    )


def load_recording(
    path: str | Path,
    face_type: FaceType = "human",
    *,
    options: ReadOptions | None = None,
    mirror: bool = False,
    fps: float | None = None,
) -> Recording:
    """Read any supported recorded file, choosing the reader by content (see the module doc). A shipped sample
    is reachable by name: ``sample:openface_smile`` (see ``servoface list samples``)."""
    from servoface.controller.errors import ControllerError
    from servoface.controller.inputs.face_files import read_blendshape_csv, read_jsonl
    from servoface.controller.inputs.fap import read_fap
    from servoface.controller.inputs.openface import _options, read_openface_csv, read_pyfeat_csv
    from servoface.controller.shipped import resolve_sample

    try:
        file = resolve_sample(path)
    except ControllerError as err:
        raise InputError(str(err)) from err
    opts = _options(options, mirror=mirror or None, fps=fps)
    kind = detect_format(file)
    if kind == "jsonl":
        return read_jsonl(file, face_type, options=opts)
    if face_type != "human":
        raise InputError(f"{file}: only JSON-lines recordings with DFACS 'aus' can drive a {face_type} head")
    if kind == "fap":
        return read_fap(file, options=opts)
    if kind == "openface":
        return read_openface_csv(file, options=opts)
    if kind == "pyfeat":
        return read_pyfeat_csv(file, options=opts)
    return read_blendshape_csv(file, options=opts)
