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


def _talk(face: Face, text: str) -> tuple[int, object, object]:
    """Speak ``text``; (the jaw's largest goal swing from rest on the wire, the run, the unbudgeted clip)."""
    from servoface.controller.au_names import head_au_names
    from servoface.controller.speech.visemes import mouth_aus

    jaw = face.head.servo_ids["jaw"]
    rest = face.pipeline.last_goals_tick[jaw]
    speech = speech_from_text(text)
    plain = speech.plan.clip("human", head_au_names(face.head) & mouth_aus("human"))
    run = say_on_face(face, speech, audio_out=False)
    swing = max(abs(t.goals_sent[jaw] - rest) for t in run.performance.traces)
    return swing, run, plain


@pytest.mark.slow
def test_a_warm_jaw_talks_with_less_jaw_on_the_emulated_head() -> None:
    """Compared with the plan at the frames that ran (a loaded machine skips frames, so no peak-to-peak
    comparisons between runs): on a cool head the budget leaves the plan alone; on a jaw the driver
    derates, the jaw sent is at most half the plan's while the lips keep theirs, and the goals reach the
    wire."""
    text = "Hello, how are you today?"
    with Face.open("human", emulate=True) as face:
        face.hold(0.1)
        cool_swing, cool, plain = _talk(face, text)
    assert cool.budget is not None and cool.budget.level == 0 and cool.budget.min_scale == 1.0
    assert cool_swing > 20, f"the cool jaw hardly moved ({cool_swing} ticks)"
    with Face.open("human", emulate=True) as face:
        jaw = face.head.servo_ids["jaw"]
        limit = face.driver.temperature_limit_c(jaw)
        servo = face.chain.servo(jaw)
        faults = face.service.subscribe("fault", maxlen=1000)  # the driver's events, read off the loop thread
        kinds: set[object] = set()
        for _ in range(80):  # the driver reads temperatures at 2 Hz: wait (as long as a loaded machine needs)
            servo.temperature_c = limit - 3.0  # past the driver's derate threshold (limit - 5); held there
            face.hold(0.25)
            snap = face.service.telemetry()
            reading = None if snap is None else snap.servos[jaw].temperature_c
            kinds |= {e.kind for e in faults.drain() if getattr(e, "servo_id", None) == jaw}
            if reading is not None and reading >= limit - 4 and FaultKind.THERMAL_DERATE in kinds:
                break
        servo.temperature_c = limit - 3.0
        warm_swing, warm, _ = _talk(face, text)
        faults.close()
    assert FaultKind.THERMAL_DERATE in kinds, "the driver did not derate the warm jaw"
    assert warm.budget is not None and warm.budget.level == 1 and warm.budget.jaw_gain == 0.5
    talking = [t for t in warm.performance.traces if plain.sample(t.t_s, {}).get("AU26", 0.0) > 0.2]
    assert talking, "no frame fell on an open vowel"
    # compared at the same frames (the twin gate may trim a frame's pose a little: sums, not equalities)
    frames = list(warm.performance.traces)
    planned = [plain.sample(t.t_s, {}) for t in frames]
    jaw_sent = sum(t.aus.get("AU26", 0.0) for t in frames)
    jaw_plan = sum(p.get("AU26", 0.0) for p in planned)
    lips_sent = sum(t.aus.get("AU25", 0.0) for t in frames)
    lips_plan = sum(p.get("AU25", 0.0) for p in planned)
    assert jaw_sent <= 0.5 * jaw_plan + 0.015 * len(frames), f"jaw {jaw_sent:.2f} vs plan {jaw_plan:.2f}"
    assert lips_sent >= 0.75 * lips_plan, f"the lips are not budgeted: {lips_sent:.2f} vs plan {lips_plan:.2f}"
    assert warm_swing > 0, "the warm jaw's goals did not reach the wire"


def test_the_account_is_kept_per_head() -> None:
    class Svc:  # a stand-in object only as a dictionary key: one account per head service
        driver = None

    a, b = Svc(), Svc()
    assert jaw_budget_for(a) is jaw_budget_for(a)
    assert jaw_budget_for(a) is not jaw_budget_for(b)
