"""`servoface check` flags an actuator range exactly when `calibrate --template` / `--builtin` refuse it.

Both put a servo's neutral at tick 2048, 4096 ticks a turn, so a joint reaching more than half a turn on
one side of neutral (``[0, 200]``, ``[-179.9, 180]``) was passed by check's span rule and refused one step
later by calibrate ("outside 0..4095; re-mount the horn"). The property: check-flags <=> calibrate-refuses,
over random ranges, neutrals and directions, and over the edges (ends exactly on tick 0 or 4095, or half a
tick past: rounding decides). And what follows from it: `calibrate --csv` takes the unedited template of
every range the other two take (a range of a few ticks once got rows on one tick: 2048, 2048, ...), and a
joint range they refuse is named in one wording, calibrate's, which check puts after the profile key. The
rule itself is also stated apart from their shared arithmetic (an ideal servo's ticks, written out here).
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from servoface.calibration.builtin import builtin_calibration
from servoface.calibration.curves import TICKS_PER_DEG
from servoface.calibration.errors import CalibrationError
from servoface.calibration.procedure import calibrate_from_csv
from servoface.calibration.spec import ServoSpec
from servoface.controller.joint_spans import range_problem
from servoface.controller.new_head.template import template_text

WHERE = "head.toml: joint[1].limits_deg"

# distances from neutral (deg) at and around the ends of an ideal servo's reach: 2047 ticks up from 2048
# (to 4095), 2048 ticks down (to 0), half a tick further (where rounding decides), and the typed values
EDGES_DEG = sorted(
    {
        *(ticks / TICKS_PER_DEG for ticks in (2046.5, 2047.0, 2047.4999, 2047.5, 2048.0, 2048.4999, 2048.5, 2049.0)),
        179.9,
        179.95,
        180.0,
        180.04,
        180.05,
        0.5 / TICKS_PER_DEG,
        1.0 / TICKS_PER_DEG,
        0.0,
    }
)


def _refusal(what: Callable[[], object]) -> str | None:
    try:
        what()
    except CalibrationError as err:
        return str(err)
    return None


def _csv_refusal(spec: ServoSpec, text: str) -> str | None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "template.csv"
        path.write_text(text)
        return _refusal(lambda: calibrate_from_csv(path, [spec], "h"))


def _agree(spec: ServoSpec) -> str | None:
    """Assert that check flags ``spec`` iff both calibrate paths refuse it, that --csv takes the unedited
    template whenever they take the range, and that a joint range is refused in one wording (check's is
    calibrate's after the key, never "re-measure": nothing was measured); return check's message."""
    why = range_problem(spec, WHERE)
    builtin = _refusal(lambda: builtin_calibration("h", [spec]))
    template = _refusal(lambda: template_text("h", [spec]))
    assert builtin == template, (spec, builtin, template)
    assert (why is not None) == (builtin is not None), (spec, why, builtin)
    if why is None:
        assert _csv_refusal(spec, template_text("h", [spec])) is None, (spec, template_text("h", [spec]))
        return None
    assert why.startswith(f"{WHERE}: "), why
    assert f"servo {spec.role!r}" in why, why
    if spec.kind == "joint":
        assert why == f"{WHERE}: {builtin}", (why, builtin)
        assert "re-measure" not in why, why
    return why


def _joint(lower: float, upper: float, neutral: float = 0.0, direction: int = 1) -> ServoSpec:
    return ServoSpec("jaw", 1, "XL430-W250", "deg", lower, upper, neutral, "joint", direction)


distance = st.one_of(
    st.sampled_from(EDGES_DEG),
    st.floats(0.0, 400.0, allow_nan=False),
    st.floats(0.0, 400.0).map(lambda d: round(d, 3)),  # as typed in head.toml
    st.floats(0.0, 0.2),  # spans around one tick
)


@settings(max_examples=600, deadline=None)
@given(
    below=distance,
    above=distance,
    neutral=st.one_of(st.just(0.0), st.floats(-200.0, 200.0).map(lambda n: round(n, 2))),
    direction=st.sampled_from((1, -1)),
    kind=st.sampled_from(("joint", "joint", "anchor")),
)
@example(below=179.9, above=180.0, neutral=0.0, direction=1, kind="joint")  # the reported case: refused
@example(below=179.9, above=180.0, neutral=0.0, direction=-1, kind="joint")  # a right-side servo: fits
@example(below=0.0, above=200.0, neutral=0.0, direction=1, kind="joint")
@example(below=180.0, above=180.0, neutral=0.0, direction=1, kind="joint")
@example(below=180.0, above=2047 / TICKS_PER_DEG, neutral=0.0, direction=1, kind="joint")  # ticks 0..4095
def test_check_flags_exactly_the_ranges_calibrate_refuses(
    below: float, above: float, neutral: float, direction: int, kind: str
) -> None:
    lower, upper = neutral - below, neutral + above
    if not lower < upper:
        return  # the profile refuses it before either command sees it (lower must be < upper)
    unit = "deg" if kind == "joint" else "mm"
    role = "jaw_r" if direction < 0 else "jaw"
    _agree(ServoSpec(role, 1, "XL430-W250", unit, lower, upper, neutral, kind, direction))  # type: ignore[arg-type]


def _ideal_end_tick(end_deg: float, neutral_deg: float, direction: int) -> float:
    """Where an ideal servo puts a joint angle, written out here apart from calibrate's code: neutral at tick
    2048, 4096 ticks a turn, ticks rising with the angle unless the servo is reversed."""
    return 2048.0 + direction * (end_deg - neutral_deg) * 4096.0 / 360.0


@settings(max_examples=400, deadline=None)
@given(
    below=st.one_of(st.floats(0.0, 400.0), st.floats(170.0, 190.0), st.floats(0.0, 0.2)),
    above=st.one_of(st.floats(0.0, 400.0), st.floats(170.0, 190.0), st.floats(0.0, 0.2)),
    neutral=st.floats(-200.0, 200.0).map(lambda n: round(n, 2)),
    direction=st.sampled_from((1, -1)),
)
@example(below=179.9, above=180.0, neutral=0.0, direction=1)
@example(below=0.0, above=0.04, neutral=0.0, direction=1)
def test_check_flags_what_an_ideal_servo_cannot_take(
    below: float, above: float, neutral: float, direction: int
) -> None:
    """The property above compares check with calibrate, which share the tick arithmetic; this states the rule
    on its own: a joint range is flagged exactly when an end rounds to a tick outside 0..4095 or both ends
    round to one tick. Ends within a millionth of a tick of a rounding edge are left to the edge tests above
    (float order decides there)."""
    lower, upper = neutral - below, neutral + above
    if not lower < upper:
        return
    ends = [_ideal_end_tick(end, neutral, direction) for end in (lower, upper)]
    if any(abs(t - math.floor(t) - 0.5) < 1e-6 for t in ends):
        return
    ticks = [math.floor(t + 0.5) for t in ends]
    refused = any(not 0 <= t <= 4095 for t in ticks) or ticks[0] == ticks[1]
    why = range_problem(_joint(lower, upper, neutral, direction), WHERE)
    assert (why is not None) == refused, (lower, upper, neutral, direction, ticks, why)


@pytest.mark.parametrize(
    ("lower", "upper", "direction", "side"),
    [
        (-179.9, 180.0, 1, "upper"),  # tick 4096
        (0.0, 200.0, 1, "upper"),
        (-200.0, 0.0, 1, "lower"),  # tick -228
        (-180.05, 0.0, 1, "lower"),  # tick -0.57 rounds to -1
        (-180.0, 179.8, -1, "lower"),  # reversed: the lower end goes up the ticks, to 4096
        (-200.0, 0.0, -1, "lower"),
    ],
)
def test_a_range_past_half_a_turn_names_the_end_and_the_fix(
    lower: float, upper: float, direction: int, side: str
) -> None:
    why = _agree(_joint(lower, upper, direction=direction))
    assert why is not None
    assert f"got [{lower:g}, {upper:g}] with neutral 0 deg (the {side} end," in why, why
    assert "re-mount the horn so neutral sits nearer the middle of the travel" in why, why
    assert "neutral_deg or narrow the range" in why, why
    other = "lower" if side == "upper" else "upper"
    assert f"the {other} end" not in why, why


@pytest.mark.parametrize(
    ("lower", "upper", "direction"),
    [
        (-180.0, 179.9, 1),  # ticks 0..4095
        (-179.9, 180.0, -1),  # reversed: 180 deg goes down to tick 0
        (-180.04, 179.95, 1),  # half a tick past either end rounds back in: ticks 0..4095
        (0.0, 0.05, 1),  # 0.57 tick: rounds to 2048..2049, one tick (calibrate warns, takes it)
        (-25.0, 25.0, 1),
    ],
)
def test_a_range_calibrate_takes_is_not_flagged(lower: float, upper: float, direction: int) -> None:
    assert _agree(_joint(lower, upper, direction=direction)) is None


@pytest.mark.parametrize(
    ("lower", "upper", "expected", "why"),
    [
        (-200.0, 200.0, "a span of at most 359.9 deg", "spans 400 deg, more than one servo turn; a typo?"),
        (-180.0, 180.0, "a span of at most 359.9 deg", "spans 360 deg, more than one servo turn; a typo?"),
        (
            0.0,
            0.04,
            "its ends on two different ticks",
            "spans 0.04 deg, less than one servo tick (0.46 tick): both ends land on tick 2048; a typo?",
        ),
    ],
)
def test_a_span_calibrate_refuses_keeps_the_span_message(lower: float, upper: float, expected: str, why: str) -> None:
    message = _agree(_joint(lower, upper))
    assert message is not None
    assert message.startswith(f"{WHERE}: expected {expected}"), message
    assert f"got [{lower:g}, {upper:g}] ({why}" in message, message


@pytest.mark.parametrize(
    ("lower", "upper", "rows"),
    [
        (0.0, 0.05, [(0.0, 2048), (0.05, 2049)]),  # was 2048, 2048, 2048, 2048, 2049
        (-0.05, 0.05, [(-0.05, 2047), (0.0, 2048), (0.05, 2049)]),
        (0.0, 0.2, [(0.0, 2048), (0.05, 2049), (0.2, 2050)]),  # 0.1 and 0.15 share ticks with 0.05 and 0.2
        (0.0, 0.0439453125, [(0.0, 2048), (0.0439, 2049)]),  # half a tick: the end row has the end's tick
    ],
)
def test_the_template_of_a_range_of_a_few_ticks_has_one_row_per_tick(
    tmp_path: Path, lower: float, upper: float, rows: list[tuple[float, int]]
) -> None:
    """`calibrate --csv` on the unedited template refused a range `--builtin` takes (ticks not strictly
    monotone): the template now keeps one row per tick, its ends first."""
    spec = _joint(lower, upper)
    text = template_text("h", [spec])
    assert [(float(t), int(k)) for _, t, k in (ln.split(",") for ln in text.splitlines()[5:])] == rows, text
    path = tmp_path / "template.csv"
    path.write_text(text)
    result = calibrate_from_csv(path, [spec], "h")
    assert (result.calibration["jaw"].min_tick, result.calibration["jaw"].max_tick) == (rows[0][1], rows[-1][1])
