"""A measurement CSV whose ticks are not monotone in the target: the message says what was found, and what
the servo's direction expects.

The direction was taken from the first two rows, so a servo whose ticks rise with the target but dip at its
first step (2048 -> 2000 -> 2190 -> ...) was told its ticks were "not strictly decreasing", and a flat first
step made every rising servo "decreasing". Now the direction is the one most steps take (on a tie, the one
from the lowest target to the highest), and the message names the step against it: its lines, targets and
ticks, whether they fall, rise or stay, and the order expected.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.calibration.errors import MeasurementCsvError
from servoface.calibration.measurements import Measurement, check_monotone_rows, read_measurements_csv


def _error(tmp_path: Path, body: str) -> MeasurementCsvError:
    path = tmp_path / "m.csv"
    path.write_text(body)
    with pytest.raises(MeasurementCsvError) as info:
        read_measurements_csv(path)
    return info.value


@pytest.mark.parametrize(
    ("body", "line", "found", "expected"),
    [
        # rising servo, its first step falls: was "not strictly decreasing"
        (
            "jaw,0,2048\njaw,6.25,2000\njaw,12.5,2190\njaw,18.75,2261\njaw,25,2332\n",
            2,
            "ticks fall from 2048 (line 1, target 0) to 2000 (line 2, target 6.25)",
            "this servo's ticks rise with the target (3 of its 4 steps; 2048 at target 0 -> 2332 at target 25): "
            "expected ticks strictly increasing in the target; re-measure line 1 or line 2",
        ),
        # rising servo, a flat first step: was "not strictly decreasing"
        (
            "jaw,0,2048\njaw,0.012,2048\njaw,0.05,2049\njaw,0.1,2050\n",
            2,
            "ticks stay at 2048 from line 1, target 0 to line 2, target 0.012",
            "this servo's ticks rise with the target (2 of its 3 steps; 2048 at target 0 -> 2050 at target 0.1): "
            "expected ticks strictly increasing in the target",
        ),
        # falling servo (a right-side one), a step that rises
        (
            "brow_r,-10,2162\nbrow_r,-2.5,2076\nbrow_r,0,2048\nbrow_r,5,2100\nbrow_r,12.5,1906\nbrow_r,20,1820\n",
            4,
            "ticks rise from 2048 (line 3, target 0) to 2100 (line 4, target 5)",
            "this servo's ticks fall with the target (4 of its 5 steps; 2162 at target -10 -> 1820 at target 20): "
            "expected ticks strictly decreasing in the target; re-measure line 3 or line 4",
        ),
        # falling servo, its first step rises: was "not strictly increasing"
        (
            "lid_r,-15,2219\nlid_r,0,2300\nlid_r,27.5,1735\nlid_r,70,1252\n",
            2,
            "ticks rise from 2219 (line 1, target -15) to 2300 (line 2, target 0)",
            "this servo's ticks fall with the target (2 of its 3 steps; 2219 at target -15 -> 1252 at target 70): "
            "expected ticks strictly decreasing in the target; re-measure line 1 or line 2",
        ),
        # rows out of target order: the steps are taken in target order, the lines are the file's
        (
            "jaw,25,2332\njaw,0,2048\njaw,12.5,2100\njaw,6.25,2119\n",
            3,
            "ticks fall from 2119 (line 4, target 6.25) to 2100 (line 3, target 12.5)",
            "expected ticks strictly increasing in the target; re-measure line 4 or line 3",
        ),
    ],
)
def test_a_step_against_the_servos_direction_is_named_with_what_was_found(
    tmp_path: Path, body: str, line: int, found: str, expected: str
) -> None:
    err = _error(tmp_path, body)
    message = str(err)
    assert err.line == line, message
    role = body.split(",", 1)[0]
    assert f"line {line}: role '{role}': {found}, but " in message, message
    assert expected in message, message


def test_the_reported_case_no_longer_says_decreasing_for_a_rising_servo(tmp_path: Path) -> None:
    message = str(_error(tmp_path, "jaw,0,2048\njaw,6.25,2000\njaw,12.5,2190\njaw,25,2332\n"))
    assert "decreasing" not in message, message
    assert "strictly increasing" in message, message


@pytest.mark.parametrize(
    ("body", "steps"),
    [
        ("jaw,0,2048\njaw,10,2100\njaw,25,2048\n", "1 step(s) up, 1 down, 0 flat"),  # no direction to go by
        ("jaw,0,2048\njaw,25,2048\n", "0 step(s) up, 0 down, 1 flat"),  # the template's ticks left as one
    ],
)
def test_ticks_with_no_direction_are_listed(tmp_path: Path, body: str, steps: str) -> None:
    message = str(_error(tmp_path, body))
    assert "role 'jaw': ticks 2048 (line 1, target 0), " in message, message
    assert f"neither rise nor fall with the target ({steps})" in message, message
    assert "expected ticks strictly increasing or strictly decreasing in the target" in message, message


def test_a_long_list_of_rows_is_cut(tmp_path: Path) -> None:
    message = str(_error(tmp_path, "".join(f"jaw,{t},2048\n" for t in range(10))))
    assert "(line 6, target 5) and 4 more neither rise nor fall" in message, message


@settings(max_examples=300, deadline=None)
@given(ticks=st.lists(st.integers(2040, 2050), min_size=2, max_size=9))
def test_the_message_says_what_the_named_step_does(ticks: list[int]) -> None:
    """Over random ticks: either they are strictly monotone (no error), or the message names one step whose
    ticks do what it says (fall / rise / stay), against the direction it says the servo has."""
    rows = [Measurement("jaw", float(i), tick, i + 1) for i, tick in enumerate(ticks)]
    steps = list(zip(ticks, ticks[1:], strict=False))
    monotone = all(b > a for a, b in steps) or all(b < a for a, b in steps)
    try:
        check_monotone_rows("m.csv", "jaw", rows)
    except MeasurementCsvError as err:
        assert not monotone
        message, line = str(err), err.line
    else:
        assert monotone
        return
    named = re.search(r"ticks (fall|rise) from (\d+) \(line (\d+), target \S+\) to (\d+) \(line (\d+),", message)
    flat = re.search(r"ticks stay at (\d+) from line (\d+), target \S+ to line (\d+),", message)
    if named is None and flat is None:
        assert "neither rise nor fall" in message, message
        up, down = sum(b > a for a, b in steps), sum(b < a for a, b in steps)
        assert up == down and ticks[0] == ticks[-1], message
        return
    if named is not None:
        verb, a, line_a, b, line_b = named.groups()
        assert (int(a), int(b)) == (ticks[int(line_a) - 1], ticks[int(line_b) - 1]), message
        assert (verb == "rise") == (int(b) > int(a)), message
        assert f"expected ticks strictly {'decreasing' if verb == 'rise' else 'increasing'}" in message, message
    else:
        assert flat is not None
        tick, line_a, line_b = flat.groups()
        assert ticks[int(line_a) - 1] == ticks[int(line_b) - 1] == int(tick), message
    assert int(line_b) == int(line_a) + 1 and line == int(line_b), message
