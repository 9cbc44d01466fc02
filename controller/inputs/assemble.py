"""What every file reader shares after parsing: rows of raw channels -> a Recording.

A reader turns each data row into a :class:`RawRow` (raw time, the channel values — blendshape scores or AU
intensities, 0..1 — or None when the tracker lost the face, an optional head pose and gaze in degrees) and
hands them to :func:`assemble`, which: converts the times (timebase.py; rows whose time goes back are bad
rows), takes the rest pose from the first ``rest_s`` seconds (rest_pose.py), maps channels to AUs (the
blendshape prior, or AUs as they are), adds head pose and gaze unless switched off, mirrors, fills lost rows
by the ``lost`` policy and builds the :class:`Recording` with its report.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from servoface.controller.inputs.blendshapes import load_blendshape_map
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.head_pose import eye_angles_aus, head_pose_aus
from servoface.controller.inputs.recorded import Recording, frames_with_policy
from servoface.controller.inputs.report import InputReport
from servoface.controller.inputs.rest_pose import RestPose
from servoface.controller.inputs.shape_ranges import ShapeRanges
from servoface.controller.inputs.sides import mirror_aus
from servoface.controller.inputs.timebase import check_fps, resolve_times
from servoface.controller.inputs.tolerance import BadRow, Tolerance
from servoface.sim.rig import FaceType

MAX_RECORDING_S = 24 * 3600.0  # a take is at most a day long; a row further from the first is a bad row
HEAD_AUS = frozenset({"AU51", "AU52", "AU53", "AU54", "AU55", "AU56", "AU57", "AU58"})
EYE_AUS = frozenset({"AU61", "AU62", "AU63", "AU64", "AU65", "AU66"})


@dataclass(frozen=True)
class ReadOptions:
    """The options every reader understands (CLI: controller/cli/input_args.py). None = the reader's default."""

    fps: float | None = None  # frame rate for files without times / --time-unit frames
    time_unit: str = "auto"
    min_confidence: float | None = None
    face_id: int | None = None
    gaze: bool = True  # eye AUs 61-66 from the file (eye-look shapes, OpenFace gaze angles, FAP eyeballs)
    head_pose: bool = True  # head AUs 51-56 from the file
    mirror: bool = False
    rest_s: float = 0.0  # take the first rest_s seconds as the user's rest pose (0 = off)
    shape_ranges: ShapeRanges | None = None
    lost: str = "hold"
    decay_s: float = 0.5
    interpolate: bool = True
    bad_rows: str = "skip"
    vergence: bool = False

    def __post_init__(self) -> None:
        check_fps(self.fps)
        if self.min_confidence is not None and not 0.0 <= self.min_confidence <= 1.0:
            raise InputError(f"min_confidence: expected 0..1, got {self.min_confidence!r}")
        if not (isinstance(self.rest_s, int | float) and 0.0 <= self.rest_s < 1e4):
            raise InputError(f"rest_s: expected 0 <= rest_s < 10000 s, got {self.rest_s!r}")
        if self.face_id is not None and (isinstance(self.face_id, bool) or not isinstance(self.face_id, int)):
            raise InputError(f"face_id: expected an integer, got {self.face_id!r}")


@dataclass
class RawRow:
    line: int
    t: float  # raw time in the file's unit (row index when there is no time column)
    values: dict[str, float] | None  # channel -> 0..1; None = lost (no face, success 0, low confidence)
    head_deg: tuple[float, float, float] | None = None  # yaw (+ own left), pitch (+ up), roll (+ top to own left)
    gaze_deg: tuple[float, float] | None = None  # yaw (+ own left), pitch (+ up)
    extra: dict[str, float] = field(default_factory=dict)  # AUs mapped by the reader itself (e.g. FAPs)


def assemble(
    rows: Sequence[RawRow],
    report: InputReport,
    opts: ReadOptions,
    tolerance: Tolerance,
    *,
    kind: str,
    time_column: str | None,
    default_fps: float,
    face_type: FaceType = "human",
    total_rows: int | None = None,
) -> Recording:
    """The Recording of ``rows`` (``kind``: ``"blendshapes"`` or ``"aus"``); see the module doc."""
    total = total_rows if total_rows is not None else len(rows) + tolerance.bad
    tolerance.check_share(total)
    if not rows:
        raise InputError(f"{report.source}: no usable data rows")
    times = resolve_times(
        [r.t for r in rows],
        column=time_column,
        unit=opts.time_unit,
        fps=opts.fps,
        default_fps=default_fps,
        report=report,
    )
    kept: list[tuple[float, RawRow]] = []
    back = 0  # rows whose time goes back: skipped, but not counted against the file (a contradicting --fps)
    for t_s, row in zip(times, rows, strict=True):
        where = f"{report.source}: line {row.line}" + (f", column {time_column!r}" if time_column else "")
        since_s = t_s - kept[0][0] if kept else 0.0
        if not (math.isfinite(t_s) and abs(since_s) <= MAX_RECORDING_S):
            # a time that overflows once in seconds (frames at a tiny fps), or a jump no take makes (1e308)
            what = f"{t_s:g} s" if not math.isfinite(t_s) else f"{t_s:g} s is {since_s:g} s after the first row"
            err = BadRow(
                f"{where}: {what}: expected a finite time within {MAX_RECORDING_S:g} s of the first row",
                "times that are not finite or more than a day from the first row",
            )
            tolerance.handle(err)
            continue
        if kept and t_s < kept[-1][0]:
            err = BadRow(f"{where}: {t_s:g} s is earlier than the row before ({kept[-1][0]:g} s)", "time going back")
            tolerance.handle(err)
            back += 1
            continue
        kept.append((t_s, row))
    tolerance.check_share(total, excluding=back)  # again: rows whose time is not finite count too
    if not kept:
        raise InputError(f"{report.source}: no usable data rows")
    rest = None
    if opts.rest_s > 0:
        rest = RestPose.from_rows([(t, r.values, r.head_deg, r.gaze_deg) for t, r in kept], opts.rest_s)
        report.rest = rest.describe(opts.rest_s)
    bmap = load_blendshape_map() if kind == "blendshapes" else None
    ranges = opts.shape_ranges
    if rest is not None and bmap is not None:
        ranges = rest.shape_ranges(ranges)
    policy_rows: list[tuple[float, dict[str, float] | None]] = []
    for t_s, row in kept:
        if row.values is None:
            policy_rows.append((t_s, None))
            continue
        values = row.values
        if bmap is not None:
            aus = bmap.to_aus(values, ranges=ranges, vergence=opts.vergence, where=f"{report.source}: line {row.line}")
        else:
            aus = dict(rest.rescale(values) if rest is not None else values)
        aus.update(row.extra)
        if row.head_deg is not None and opts.head_pose:
            ypr = rest.head(row.head_deg) if rest is not None else row.head_deg
            aus.update(head_pose_aus(*ypr))
        if row.gaze_deg is not None and opts.gaze:
            yaw, pitch = rest.gaze(row.gaze_deg) if rest is not None else row.gaze_deg
            aus.update(eye_angles_aus(yaw, pitch))
        aus = _switch(aus, opts)
        policy_rows.append((t_s, mirror_aus(aus, face_type) if opts.mirror else aus))
    frames, report.held = frames_with_policy(policy_rows, face_type, lost=opts.lost, decay_s=opts.decay_s)
    report.rows = len(frames)
    return Recording(frames, face_type, interpolate=opts.interpolate, source=report.source, report=report)


def _switch(aus: Mapping[str, float], opts: ReadOptions) -> dict[str, float]:
    out = {k: v for k, v in aus.items() if math.isfinite(v)}
    if not opts.head_pose:
        out = {k: v for k, v in out.items() if k not in HEAD_AUS}
    if not opts.gaze:
        out = {k: v for k, v in out.items() if k not in EYE_AUS}
    return out


def fill_cells(values: dict[str, float], last: dict[str, float], report: InputReport) -> dict[str, float] | None:
    """NaN cells of a row: all NaN -> None (no face); some -> the channel's previous value (0 before any),
    counted. ``last`` is updated with the row's values."""
    missing = [k for k, v in values.items() if math.isnan(v)]
    if len(missing) == len(values):
        return None
    for k in missing:
        values[k] = last.get(k, 0.0)
    report.cells_filled += len(missing)
    last.update(values)
    return values
