"""DFACS ordered events -> timed keyframes, and the testable sequencing rules of dfacs-dog.md §4."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st
from servoface.controller.errors import TimelineError
from servoface.controller.timeline import EventTiming, Timeline, events_clip, parse_events, recipe_events
from servoface.controller.timeline.dfacs import LONDRA_RECIPES, schedule


def table_recipe(name: str):  # the thesis order (Table 5.5) with the default intensity
    return parse_events(LONDRA_RECIPES[name], field=name)


def overlaps(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return a[0] < b[1] and b[0] < a[1]


def test_event_notations() -> None:
    events = parse_events([14, -9, "AU7", "-au5", {"au": "AU7", "value": -0.3}, {"au": "AU16", "iterations": 3}])
    assert [(e.au, e.sign) for e in events] == [
        ("AU14", 1),
        ("AU9", -1),
        ("AU7", 1),
        ("AU5", -1),
        ("AU7", -1),
        ("AU16", 1),
    ]
    timing = EventTiming(intensity=0.5)
    assert [e.target(timing) for e in events[:5]] == [0.5, -0.5, 0.5, -0.5, -0.3]
    assert events[5].iterations == 3


@pytest.mark.parametrize(
    ("token", "needle"),
    [
        ("AU7c", r"events\[0\]: 'AU7c' is not an event; expected 'AU14' or '-AU14'"),
        (0, r"events\[0\]: 0 is not an AU"),
        ({"au": "AU7", "value": 2}, r"events\[0\]\.value: expected a signed DFACS intensity -1..1"),
        ({"value": 0.3}, r"events\[0\]\.au: missing"),
        ({"au": "AU7", "speed": 1}, r"events\[0\]: unknown key"),
        (1.5, r"events\[0\]: expected an AU event"),
    ],
)
def test_bad_events_name_their_index(token: object, needle: str) -> None:
    with pytest.raises(TimelineError, match=needle):
        parse_events([token])


def test_anger_plays_in_the_recipe_order() -> None:
    # retract eyes, lids down, lip raise, mouth corners back, ears forward, jaw open, tongue tip out
    placed = schedule(table_recipe("anger"))
    assert [p.event.au for p in placed] == ["AU14", "AU4", "AU1", "AU2", "AU5", "AU7", "AU18"]
    starts = [p.start_s for p in placed]
    assert starts == sorted(starts) and len(set(starts)) == len(starts)
    assert starts == pytest.approx([0.15 * k for k in range(7)])  # default spacing, all different AUs
    by_au = {p.event.au: p.start_s for p in placed}
    # §4: lips (AU1) and mouth corners (AU2) move before the ears (AU5)
    assert by_au["AU1"] < by_au["AU5"] and by_au["AU2"] < by_au["AU5"]


def test_anger_clip_reaches_each_target_in_order() -> None:
    clip = events_clip(table_recipe("anger"))
    onsets = clip.onsets()
    firsts = {au: moves[0][0] for au, moves in onsets.items()}
    order = sorted(firsts, key=firsts.__getitem__)
    assert order == ["AU14", "AU4", "AU1", "AU2", "AU5", "AU7", "AU18"]
    end = clip.sample(clip.duration_s, {})
    assert end == pytest.approx({au: 0.8 for au in order})
    # before an AU's onset it stays where the face was (events start from the current face)
    assert clip.sample(0.2, {"AU5": -0.4})["AU5"] == pytest.approx(-0.4)


@pytest.mark.parametrize("source", ["table", "library"])
def test_affection_head_pitch_and_yaw_never_overlap(source: str) -> None:
    events = table_recipe("affection_i") if source == "table" else recipe_events("affection_i")
    placed = schedule(events)
    head = [(p.start_s, p.end_s) for p in placed if p.event.number in (9, 10)]
    assert len(head) == 9
    for a, b in itertools.combinations(head, 2):
        assert not overlaps(a, b)
    # and the up/down/left/right alternation lands in order
    assert [p.event.sign for p in placed if p.event.number == 9][:4] == [1, -1, 1, -1]


def test_affection_on_a_timeline_moves_only_one_head_axis_at_a_time() -> None:
    tl = Timeline("dog")
    tl.play(events_clip(table_recipe("affection_i")), 0.0)
    dt = 0.01
    steps = int(tl.end_s / dt)
    prev = tl.sample_aus(0.0)
    for k in range(1, steps + 1):
        now = tl.sample_aus(k * dt)
        moving = [au for au in ("AU9", "AU10") if abs(now.get(au, 0.0) - prev.get(au, 0.0)) > 1e-9]
        assert len(moving) <= 1, f"pitch and yaw both move at t={k * dt:.2f}"
        prev = now


def test_smelling_alternates_equal_open_close_phases() -> None:
    timing = EventTiming(move_s=0.15, dwell_s=0.25)
    placed = schedule(list(table_recipe("smelling")) * 4, timing)
    starts = [p.start_s for p in placed]
    phases = [b - a for a, b in zip(starts, starts[1:], strict=False)]
    assert phases == pytest.approx([0.4] * 7)
    assert [p.target > 0 for p in placed] == [True, False] * 4
    clip = events_clip(table_recipe("smelling"), timing, repeat=4)
    assert clip.sample(0.15, {})["AU3"] == pytest.approx(0.8)  # open
    assert clip.sample(0.55, {})["AU3"] == pytest.approx(-0.8)  # closed


def test_attention_eyes_lead_and_ears_rise_before_the_head() -> None:
    placed = schedule(table_recipe("attention"))
    first = {p.event.number: p.start_s for p in placed}
    assert first[12] < first[11] and first[12] < first[9]  # eyes lead the head
    assert first[6] < first[11] and first[6] < first[9]  # ears before the head


def test_pulse_and_cyclic_events_return_to_where_they_were() -> None:
    clip = events_clip(parse_events(["AU15", {"au": "AU16", "iterations": 3}]), EventTiming(pulse_s=0.2, cycle_s=0.5))
    assert clip.sample(0.1, {})["AU15"] == pytest.approx(0.8)
    assert clip.sample(0.2, {})["AU15"] == pytest.approx(0.0)
    lick = clip.onsets()["AU16"]
    assert len([m for m in lick if m[2] > 0]) == 3  # three strokes
    assert clip.sample(clip.duration_s, {})["AU16"] == pytest.approx(0.0)


def test_release_returns_to_neutral_and_default_holds() -> None:
    held = events_clip(table_recipe("fear"))
    assert held.end_pose({}) == pytest.approx({"AU14": -0.8, "AU5": -0.8, "AU9": -0.8})
    released = events_clip(table_recipe("fear"), EventTiming(release_s=0.5))
    assert released.end_pose({}) == pytest.approx({"AU14": 0.0, "AU5": 0.0, "AU9": 0.0})
    assert released.duration_s == pytest.approx(held.duration_s + 0.5)


def test_library_recipes_are_used_when_present_and_table_is_the_fallback() -> None:
    anger = recipe_events("anger")
    assert [e.au for e in anger][:3] == ["AU14", "AU4", "AU1"]
    assert recipe_events("anger", use_library=False) == table_recipe("anger")
    with pytest.raises(TimelineError, match="dog expression 'joy' is unknown; expected one of"):
        recipe_events("joy")


def test_timing_validation() -> None:
    with pytest.raises(TimelineError, match="move_s: expected a finite duration"):
        EventTiming(move_s=-1)
    with pytest.raises(TimelineError, match="intensity: expected a magnitude 0..1"):
        EventTiming(intensity=1.5)
    with pytest.raises(TimelineError, match="repeat: expected an integer >= 1"):
        events_clip(table_recipe("fear"), repeat=0)


EVENT_AUS = ["AU1", "AU1L", "AU1R", "AU3", "AU5", "AU7", "AU9", "AU10", "AU11", "AU14"]


@given(st.lists(st.tuples(st.sampled_from(EVENT_AUS), st.sampled_from([-1, 1])), min_size=1, max_size=12))
def test_property_any_event_list_keeps_order_and_never_overlaps_a_joint(
    events: list[tuple[str, int]],
) -> None:
    tokens = [("-" if sign < 0 else "") + au for au, sign in events]
    placed = schedule(parse_events(tokens))
    starts = [p.start_s for p in placed]
    assert all(b > a for a, b in zip(starts, starts[1:], strict=False))  # strictly in the given order
    for a, b in itertools.combinations(placed, 2):
        bilateral = a.event.au[-1] not in "LR" or b.event.au[-1] not in "LR"
        same_au = a.event.number == b.event.number and (a.event.au == b.event.au or bilateral)
        same_joint = same_au or {a.event.number, b.event.number} <= {9, 10, 11}
        if same_joint:
            assert not overlaps((a.start_s, a.end_s), (b.start_s, b.end_s)), (a, b)
    assert placed[0].start_s == 0.0


def test_left_and_right_sides_move_together_but_bilateral_waits() -> None:
    placed = schedule(parse_events(["AU1L", "AU1R", "AU1"]))
    assert placed[1].start_s == pytest.approx(0.15)  # the right side does not wait for the left
    assert placed[2].start_s >= placed[1].end_s  # the bilateral AU waits for both sides
