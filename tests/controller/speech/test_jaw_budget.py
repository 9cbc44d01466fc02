"""The jaw's thermal budget for long speech: the account, its cap, the driver's thermal levels, and on the
emulated head a warm jaw servo that talks with less jaw (checked from the wire)."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.face import Face
from servoface.controller.speech.errors import SpeechError
from servoface.controller.speech.jaw_budget import DEFAULT_MAX_DUTY, JawBudget, JawThermal
from servoface.controller.speech.lipsync import speech_from_text
from servoface.controller.speech.say import jaw_budget_for, say_on_face
from servoface.controller.speech.visemes import FEATURES
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.snapshot import FaultKind

SENTENCE = (
    "Good morning and welcome to the museum. My name is Ada, and I am a robot head built from twenty "
    "servos. Please come closer, look at my face, and tell me how you feel today."
)
OPEN, PART = FEATURES.index("open"), FEATURES.index("part")


@pytest.fixture(scope="module")
def plan():  # type: ignore[no-untyped-def]
    return speech_from_text(SENTENCE).plan


def test_one_sentence_is_left_alone(plan) -> None:  # type: ignore[no-untyped-def]
    out, report = JawBudget().apply(plan, 0.0)
    assert report.min_scale == 1.0 and report.scaled_share == 0.0
    assert np.array_equal(out.features, plan.features)
    assert 0 < report.account_after < DEFAULT_MAX_DUTY


def test_long_speech_keeps_the_account_within_the_budget(plan) -> None:  # type: ignore[no-untyped-def]
    budget, t = JawBudget(), 0.0
    reports = []
    for _ in range(20):  # ~3.6 minutes without a pause
        out, report = budget.apply(plan, t)
        t += plan.duration_s
        reports.append(report)
        assert report.peak_account <= DEFAULT_MAX_DUTY + 1e-9
        assert np.all(out.features[:, OPEN] <= plan.features[:, OPEN] + 1e-12), "the budget only lowers the jaw"
        assert np.array_equal(out.features[:, PART], plan.features[:, PART]), "the lips are not budgeted"
    assert reports[0].min_scale == 1.0
    assert reports[-1].min_scale < 0.95 and reports[-1].scaled_share > 0.5, "continuous talk was not capped"
    assert reports[-1].min_scale > 0.5, "the cap is a quieter jaw, not a shut one"
    # five minutes of silence: the account has decayed and a sentence is free again
    later, report = budget.apply(plan, t + 300.0)
    assert report.account_before < DEFAULT_MAX_DUTY / 4 and report.min_scale == 1.0


def test_the_drivers_thermal_levels_set_the_budget(plan) -> None:  # type: ignore[no-untyped-def]
    policy = FaultPolicy()
    limit = 70.0
    b = JawBudget(policy=policy)
    cool = b.limits(JawThermal(30.0, limit))
    tapering = b.limits(JawThermal(limit - policy.thermal_margin_c - 5.0, limit))
    derate = b.limits(JawThermal(limit - policy.thermal_margin_c + 1.0, limit))
    rising = b.limits(JawThermal(50.0, limit, seconds_to_limit_s=60.0))  # predicted within 120 s: derate
    off = b.limits(JawThermal(limit - 0.5, limit))
    assert cool == (DEFAULT_MAX_DUTY, 1.0, 0)
    assert tapering[2] == 0 and DEFAULT_MAX_DUTY * 0.25 < tapering[0] < DEFAULT_MAX_DUTY
    assert derate == (DEFAULT_MAX_DUTY * 0.25, 0.5, 1) == rising
    assert off == (0.0, 0.0, 2)
    out, report = JawBudget().apply(plan, 0.0, JawThermal(limit - 0.5, limit))
    assert report.level == 2 and float(out.features[:, OPEN].max()) == 0.0
    assert np.array_equal(out.features[:, PART], plan.features[:, PART])
    out, report = JawBudget().apply(plan, 0.0, JawThermal(limit - 3.0, limit))
    assert float(out.features[:, OPEN].max()) <= 0.5 * float(plan.features[:, OPEN].max()) + 1e-9


def test_bad_settings_are_refused() -> None:
    with pytest.raises(SpeechError, match="max_duty"):
        JawBudget(max_duty=-0.1)
    with pytest.raises(SpeechError, match="window_s"):
        JawBudget(window_s=float("nan"))


def _jaw_swing(face: Face, text: str) -> tuple[int, int, object]:
    jaw = face.head.servo_ids["jaw"]
    lip = face.head.servo_ids["lower_lip"]
    rest_jaw, rest_lip = face.pipeline.last_goals_tick[jaw], face.pipeline.last_goals_tick[lip]
    run = say_on_face(face, speech_from_text(text), audio_out=False)
    swing = max(abs(t.goals_sent[jaw] - rest_jaw) for t in run.performance.traces)
    lips = max(abs(t.goals_sent[lip] - rest_lip) for t in run.performance.traces)
    return swing, lips, run


@pytest.mark.slow
def test_a_warm_jaw_talks_with_less_jaw_on_the_emulated_head() -> None:
    text = "Hello, how are you today?"
    with Face.open("human", emulate=True) as face:
        face.hold(0.1)
        cool_swing, cool_lips, _ = _jaw_swing(face, text)
    with Face.open("human", emulate=True) as face:
        jaw = face.head.servo_ids["jaw"]
        limit = face.driver.temperature_limit_c(jaw)
        face.chain.servo(jaw).temperature_c = limit - 3.0  # past the driver's derate threshold (limit - 5)
        deadline = 0
        while deadline < 40:  # the driver reads temperatures at 2 Hz: wait for its reading (and reaction)
            face.hold(0.25)
            snap = face.service.telemetry()
            if (
                snap is not None
                and snap.servos[jaw].temperature_c is not None
                and snap.servos[jaw].temperature_c >= limit - 4
            ):
                break
            deadline += 1
        warm_swing, warm_lips, run = _jaw_swing(face, text)
        kinds = {e.kind for e in face.driver.events if e.servo_id == jaw}
    assert FaultKind.THERMAL_DERATE in kinds, "the driver did not derate the warm jaw"
    assert run.budget is not None and run.budget.level == 1 and run.budget.jaw_gain == 0.5
    assert cool_swing > 20, f"the cool jaw hardly moved ({cool_swing} ticks)"
    assert warm_swing <= 0.6 * cool_swing, f"warm jaw swing {warm_swing} ticks vs cool {cool_swing}"
    assert warm_lips >= 0.9 * cool_lips, "the lips should still talk in full"


def test_the_account_is_kept_per_head() -> None:
    class Svc:  # a stand-in object only as a dictionary key: one account per head service
        driver = None

    a, b = Svc(), Svc()
    assert jaw_budget_for(a) is jaw_budget_for(a)
    assert jaw_budget_for(a) is not jaw_budget_for(b)
