"""`servoface play` of a script with a `say` cue, checked from the emulator's side of a real pty (the chain in
its own process, `servoface emulate --state-file`): the cue is spoken — the mouth servos' goals on the wire
open and close with the words while the brows and lids stay where they are — and a bad say cue is refused
naming its field before a single packet reaches the chain."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from servoface.controller.cli import main

from tests.integration.safe_stop_rig import bench, goals_outside_limits, torque_on_ids

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")

WORDS = "Bob bought a big blue balloon."
CUE_AT_S = 0.4
HEAD = '[script]\nface = "human"\n[[play]]\nat_s = 0.4\n'
JAW, UPPER_LIP, LOWER_LIP = 18, 11, 16
STILL = (1, 2, 3, 4, 5, 6, 7)  # brows and lids: not the speech track's


def _neutral() -> dict[int, int]:
    from servoface.calibration import load_calibration
    from servoface.sim.heads import load_head

    cal = load_calibration(load_head("human").calibration_path)
    return {s.servo_id: s.neutral_tick for s in cal.servos}


def _goals(state: dict, servo_id: int) -> list[tuple[float, int]]:  # type: ignore[type-arg]
    return [(t, g) for t, sid, g in state["goal_writes"] if sid == servo_id]


@pytest.mark.parametrize(
    "body, field",
    [
        ('say = ""', "play[0].say"),
        ("say = 3", "play[0].say"),
        ('say = "hi"\nvoice = "../x"', "play[0].voice"),
        ('say = "hi"\nvoice = "zz-nope"', "play[0].voice"),  # espeak-ng has no such voice
        ('say = "hi"\nlibrary = "happiness"', "play[0]"),
    ],
)
def test_a_bad_say_cue_names_its_field_and_sends_nothing(
    tmp_path: Path, body: str, field: str, capsys: pytest.CaptureFixture[str]
) -> None:
    script = tmp_path / "bad.toml"
    script.write_text(HEAD + body + "\n")
    with bench(tmp_path) as b:
        status = main(["play", str(script), "--port", b.port])
        err = capsys.readouterr().err
        state = b.final_state()
    assert status == 2, err
    assert f"{field}:" in err and "bad.toml" in err and "Traceback" not in err, err
    assert state["packets_received"] == 0, "a packet reached the chain"


def test_play_speaks_a_say_cue_and_the_mouth_moves_on_the_wire(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from servoface.controller.speech.lipsync import speech_from_text

    script = tmp_path / "talk.toml"
    script.write_text(HEAD + f'say = "{WORDS}"\n')
    with bench(tmp_path) as b:
        status = main(["play", str(script), "--port", b.port])
        out, err = capsys.readouterr()
        state = b.final_state()
    assert status == 0, out + err
    said = [line for line in out.splitlines() if line.startswith("said ")]
    assert len(said) == 1 and WORDS[:30] in said[0] and "on the speech track" in said[0], out
    # no sound card here: the sound is not played and the monotonic clock is master (README, Speech)
    clock = "monotonic" if "no sound output" in said[0] else "device"
    assert f"the mouth followed the {clock} clock" in said[0], said
    assert torque_on_ids(state) == [] and goals_outside_limits(state) == []

    neutral = _neutral()
    jaw = _goals(state, JAW)
    open_tick = neutral[JAW] + 20  # the jaw's goal rises as it opens (human head calibration)
    opened = [t for t, g in jaw if g > open_tick]
    assert max(g for _, g in jaw) - neutral[JAW] > 40, "the jaw never opened"
    # it opens and closes with the syllables (the bilabials of Bob, bought, big, blue, balloon close it)
    openings, was_open = 0, False
    for _, g in jaw:
        if g > open_tick and not was_open:
            openings, was_open = openings + 1, True
        elif g < neutral[JAW] + 8:
            was_open = False
    assert openings >= 3, (openings, jaw)
    spoken_s = speech_from_text(WORDS).duration_s
    assert 0.5 * spoken_s <= opened[-1] - opened[0] <= spoken_s + 0.5, (opened[0], opened[-1], spoken_s)
    for lip in (UPPER_LIP, LOWER_LIP):
        ticks = [g for _, g in _goals(state, lip)]
        assert max(ticks) - min(ticks) > 10, f"servo {lip} (a lip) did not move"
    for sid in STILL:
        assert all(abs(g - neutral[sid]) <= 2 for _, g in _goals(state, sid)), f"servo {sid} moved"
