"""Speech on the emulated head, checked from the wire: the mouth back at its resting goals within 150 ms
of the end of the audio, and an expression held while talking keeps its brows and lids."""

from __future__ import annotations

import pytest
from servoface.controller.face import Face
from servoface.controller.speech.lipsync import speech_from_text
from servoface.controller.speech.say import say_on_face

TEXT = "Bob bought a big blue balloon for the baby."
MOUTH_ROLES = ("jaw", "lower_lip", "lip_pucker", "upper_lip")
BROW_LID_ROLES = ("brow_inner_l", "brow_inner_r", "brow_outer_l", "brow_outer_r", "upper_lid_l", "upper_lid_r")


@pytest.fixture(scope="module")
def talking() -> tuple:
    speech = speech_from_text(TEXT)
    with Face.open("human", emulate=True) as face:
        face.hold(0.1)
        rest = dict(face.pipeline.last_goals_tick)
        face.express("surprise", hold_s=0.3)
        before = dict(face.pipeline.last_goals_tick)
        run = say_on_face(face, speech, audio_out=False)
        writes = face.chain.goal_writes()
        ids = face.head.servo_ids
        yield speech, run, before, writes, ids, rest


@pytest.mark.slow
def test_the_mouth_moves_while_speaking(talking: tuple) -> None:
    speech, run, before, _, ids, _ = talking
    jaw = ids["jaw"]
    during = [t.goals_sent[jaw] for t in run.performance.traces if 0.3 < t.t_s < speech.plan.audio_end_s - 0.2]
    assert max(during) - min(during) > 30, "the jaw did not move with the speech"
    closures = [t for t in run.performance.traces if t.aus.get("AU24", 0) > 0.5]
    assert closures, "no lip closure for the bilabials (b, m, p)"


@pytest.mark.slow
def test_mouth_is_back_at_rest_within_150_ms_of_the_audio_end(talking: tuple) -> None:
    speech, run, before, writes, ids, _ = talking
    end = speech.plan.audio_end_s  # mouth clock: the sound ends here
    late = [t for t in run.performance.traces if t.t_s >= end + 0.15]
    assert late, "the run stopped before the audio end + 150 ms"
    for role in MOUTH_ROLES:
        sid = ids[role]
        for trace in late:
            assert abs(trace.goals_sent[sid] - before[sid]) <= 2, (
                f"{role} (servo {sid}) at t={trace.t_s:.3f} s is {trace.goals_sent[sid]}, rest {before[sid]} "
                f"({trace.t_s - end:.3f} s after the audio ended)"
            )
    # and those goals reached the wire: the last goal written to each mouth servo is its resting goal
    for role in MOUTH_ROLES:
        sid = ids[role]
        last = [g for _, i, g in writes if i == sid][-1]
        assert abs(last - before[sid]) <= 2, f"{role}: last goal on the wire {last}, rest {before[sid]}"


@pytest.mark.slow
def test_an_expression_held_while_talking_keeps_its_brows_and_lids(talking: tuple) -> None:
    speech, run, before, _, ids, rest = talking
    raised = [r for r in BROW_LID_ROLES if abs(before[ids[r]] - rest[ids[r]]) > 15]
    assert len(raised) >= 4, f"surprise did not move the brows/lids off rest: {raised}"
    for role in BROW_LID_ROLES:
        sid = ids[role]
        values = {t.goals_sent[sid] for t in run.performance.traces}
        assert max(abs(v - before[sid]) for v in values) <= 2, f"{role} moved while talking: {sorted(values)}"
