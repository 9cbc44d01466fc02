"""Every path that drives the mouth from speech goes through the one jaw budget; a script's say cues are on
the speech track only; a stop ends the sound (AudioOut.stop, at the sound device's boundary)."""

from __future__ import annotations

import sys
import threading
import time
import types
from typing import Any

import numpy as np
import pytest
from servoface.controller.errors import ControllerError
from servoface.controller.script import parse_script
from servoface.controller.speech.jaw_budget import DEFAULT_MAX_DUTY, JawBudget, JawThermal
from servoface.controller.speech.jaw_clip import budget_clip
from servoface.controller.speech.lipsync import speech_from_text


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("hot", [False, True])
def test_edited_mouth_keys_are_budgeted_as_the_plan_they_were_written_from(seed: int, hot: bool) -> None:
    """The keys `say --out` writes (the plan's clip) through the clip budget give the jaw the plan budget
    gives (within the keys' simplification tolerance), and the same account; the lips untouched."""
    rng = np.random.default_rng(seed)
    words = ["hello", "bob", "bought", "a", "big", "blue", "balloon", "today", "mama", "papa", "open", "wide"]
    text = " ".join(rng.choice(words, size=int(rng.integers(4, 10))))
    plan = speech_from_text(text).plan
    jaw = JawThermal(65.0, 70.0) if hot else None  # limit - 5 +0: the driver derates (level 1)
    start = float(rng.uniform(0, 100))
    a, b = JawBudget(), JawBudget()
    a.account = b.account = DEFAULT_MAX_DUTY * float(rng.uniform(0.6, 1.0))  # a head that talked a lot
    a._t_s = b._t_s = start  # noqa: SLF001 - the account as of the utterance's start
    planned, report_a = a.apply(plan, start, jaw)
    keys = plan.clip("human")
    edited, report_b = budget_clip(keys, "human", start, b, jaw)
    want = planned.clip("human")
    assert report_b.level == report_a.level and report_b.jaw_gain == report_a.jaw_gain
    assert report_a.min_scale < 1.0, "the budget did not bite: the test shows nothing"
    assert abs(report_b.account_after - report_a.account_after) < 0.1 * DEFAULT_MAX_DUTY
    for t in np.arange(0.0, plan.duration_s, 0.01):
        got, exp, raw = edited.sample(t, {}), want.sample(t, {}), keys.sample(t, {})
        assert abs(got.get("AU26", 0.0) - exp.get("AU26", 0.0)) < 0.05, (t, got, exp)
        assert got.get("AU25", 0.0) == raw.get("AU25", 0.0), "the lips are not the budget's"


def test_a_say_cue_on_another_track_is_refused_naming_the_field() -> None:
    text = '[script]\nface = "human"\n[[play]]\nat_s = 0.2\nsay = "Hello"\ntrack = "narrator"\n'
    with pytest.raises(ControllerError, match=r"play\[0\]\.track.*speech track"):
        parse_script(text, source="t.toml")
    ok = parse_script(text.replace('"narrator"', '"speech"'), source="t.toml")
    assert "speech" in ok.timeline.layer_names


def _say_out(tmp: Any, text: str) -> Any:
    from servoface.controller.script import load_script
    from servoface.controller.speech.say import write_outputs

    _, path = write_outputs(speech_from_text(text), "human", tmp)
    return load_script(path)


def _jaw_swing(chain: Any, jaw: int) -> int:
    """How far the jaw goals the emulator received (since its log was cleared) swing."""
    goals = [g for _, sid, g in chain.goal_writes() if sid == jaw]
    return max(goals) - min(goals) if goals else 0


@pytest.mark.slow
def test_a_warm_jaw_that_talked_a_lot_talks_less_from_a_sound_file_on_the_wire(tmp_path: Any) -> None:
    """The speech track played with its sound file (what `say --out` writes) on a jaw 1 degree C below the
    driver's derate threshold (the driver itself does nothing yet; the budget tapers) whose account is full
    from talking: the budget scales the jaw down as it would a say cue's, and the jaw goals the emulator
    receives swing at most ~60 % as far as on a cool, rested head; the lips still move."""
    from servoface.controller.face import Face
    from servoface.controller.speech.say import jaw_budget_for
    from servoface.controller.speech.script_play import play_script_speaking

    script = _say_out(tmp_path, "Wow, a wide open mouth. Papa, mama, aha, aha.")
    swings, reports = [], []
    for warm in (False, True):
        with Face.open("human", emulate=True, wire_time=False) as face:
            jaw = face.head.servo_ids["jaw"]
            if warm:
                limit = face.driver.temperature_limit_c(jaw)
                below = limit - face.driver.policy.thermal_margin_c - 1.0
                face.chain.servo(jaw).temperature_c = below
                for _ in range(80):  # the driver reads temperatures at 2 Hz
                    face.hold(0.25)
                    snap = face.service.telemetry()
                    if snap is not None and (snap.servos[jaw].temperature_c or 0.0) >= below - 0.5:
                        break
                account = jaw_budget_for(face.service)
                account.account, account._t_s = DEFAULT_MAX_DUTY, time.monotonic()  # noqa: SLF001 - a long talk
            face.chain.log.clear()
            spoken = play_script_speaking(face, script, audio_out=False)
            swings.append(_jaw_swing(face.chain, jaw))
            assert spoken.audio is not None and spoken.audio.mouth
            reports.append(spoken.audio.budget)
            assert any("jaw budget: " in line for line in spoken.lines()) == warm, spoken.lines()
            lips = [t.aus.get("AU25", 0.0) for t in spoken.performance.traces]
            assert max(lips) > 0.3, "the lips did not move"
    cool, warm_report = reports
    assert cool is not None and cool.level == 0 and cool.min_scale == 1.0
    assert warm_report is not None and warm_report.level == 0 and warm_report.budget < DEFAULT_MAX_DUTY
    assert warm_report.min_scale <= 0.5 + 1e-9, warm_report
    assert swings[0] > 20, f"the cool jaw hardly moved ({swings[0]} ticks)"
    assert 0 < swings[1] <= 0.6 * swings[0], f"warm jaw {swings[1]} ticks vs cool {swings[0]}"


class _FakeStream:
    """PortAudio's OutputStream as sounddevice shows it: a callback thread asking for 10 ms buffers."""

    instances: list[_FakeStream] = []

    def __init__(self, *, samplerate: int, channels: int, dtype: str, callback: Any, finished_callback: Any) -> None:
        self.rate, self.callback, self.finished = samplerate, callback, finished_callback
        self.latency = 0.01
        self.frames_out = 0
        self.aborted = self.closed = False
        self.aborted_at: float | None = None  # time.monotonic() of the abort: when the sound ended
        self._halt = threading.Event()
        self._thread: threading.Thread | None = None
        _FakeStream.instances.append(self)

    def start(self) -> None:
        def pump() -> None:
            sd = sys.modules["sounddevice"]
            n = self.rate // 100
            while not self._halt.is_set():
                buf = np.zeros((n, 1), dtype=np.float32)
                now = time.monotonic()
                info = types.SimpleNamespace(outputBufferDacTime=now + 0.01, currentTime=now)
                try:
                    self.callback(buf, n, info, None)
                except (sd.CallbackStop, sd.CallbackAbort):
                    break
                self.frames_out += n
                time.sleep(0.01)
            self.finished()

        self._thread = threading.Thread(target=pump, daemon=True)
        self._thread.start()

    def abort(self) -> None:
        self.aborted = True
        self.aborted_at = time.monotonic()
        self._halt.set()

    def close(self) -> None:
        self.closed = True
        self._halt.set()


@pytest.fixture
def fake_device(monkeypatch: pytest.MonkeyPatch) -> type[_FakeStream]:
    """The smallest stand-in for the sound library (PortAudio is not installed here): servoface's own code
    runs as it would with a sound card."""
    mod = types.ModuleType("sounddevice")

    class CallbackStop(Exception):  # noqa: N818 - sounddevice's names
        pass

    class CallbackAbort(Exception):  # noqa: N818
        pass

    mod.CallbackStop, mod.CallbackAbort = CallbackStop, CallbackAbort  # type: ignore[attr-defined]
    mod.OutputStream = _FakeStream  # type: ignore[attr-defined]
    mod.query_devices = lambda kind=None: {"name": "fake output"}  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "sounddevice", mod)
    _FakeStream.instances.clear()
    return _FakeStream


def test_audio_out_stop_ends_the_sound_at_once(fake_device: type[_FakeStream]) -> None:
    from servoface.controller.speech.playback import open_audio_out

    out = open_audio_out()
    assert out.available
    rate = 16000
    out.play_at(np.zeros(rate * 5), rate, time.monotonic())  # 5 s of sound
    time.sleep(0.3)
    out.stop()
    t = time.monotonic()
    out.wait(2.0)
    assert time.monotonic() - t < 0.5
    (stream,) = fake_device.instances
    assert stream.aborted and stream.closed and stream.frames_out < rate * 2, stream.frames_out
    assert "stopped at" in out.reason, out.reason
    late = open_audio_out()
    late.play_at(np.zeros(rate), rate, time.monotonic() + 5.0)
    late.stop()
    late.wait(2.0)
    assert fake_device.instances[-1].frames_out == 0 and "before it started" in late.reason


@pytest.mark.slow
@pytest.mark.parametrize("how", ["estop", "stop", "close"])
def test_a_stop_mid_cue_ends_its_sound(fake_device: type[_FakeStream], how: str) -> None:
    """A script with a long say cue speaking on a head; an e-stop, a stop of the speech track or Face.close
    mid-cue: the sound's stream is aborted within a few polls, long before the sound's end."""
    from servoface.controller.face import Face
    from servoface.controller.speech.script_play import submit_script_speaking

    text = '[script]\nface = "human"\n[[play]]\nat_s = 0.0\nsay = "' + "Hello there, how are you today? " * 4 + '"\n'
    script = parse_script(text, source="long.toml")
    face = Face.open("human", emulate=True, wire_time=False)
    try:
        face.hold(0.1)
        handle, run = submit_script_speaking(face.service, script)
        (scheduled,) = run.scheduled
        assert scheduled.out is not None and scheduled.out.available
        deadline = time.monotonic() + 10
        while not fake_device.instances or fake_device.instances[0].frames_out < 8000:  # 0.5 s played
            assert time.monotonic() < deadline, "the sound did not start"
            time.sleep(0.02)
        t = time.monotonic()
        if how == "estop":
            face.service.estop("test")
        elif how == "stop":
            face.service.stop("speech")
        else:
            face.close()
        scheduled.out.wait(3.0)
    finally:
        face.close()
    stream = fake_device.instances[0]
    length = len(run.kept[0][1].samples)
    assert stream.aborted and stream.frames_out < length * 0.6, (stream.frames_out, length)
    # when the sound ended, not when the call returned: Face.close goes on to ease the open mouth home and
    # turn torque off (~0.8 s more) after it has stopped the sound
    assert stream.aborted_at is not None
    took = stream.aborted_at - t
    assert took < 1.0, f"the sound went on for {took:.2f} s after the {how}"


def test_say_cues_beside_a_sound_files_mouth_keys_are_refused_before_anything_moves(tmp_path: Any) -> None:
    """A `say --out` script (mouth keys for its sound file on the speech track) with a say cue added (the
    studio's speech lane): the keys could not follow the sound nor the jaw budget, so it is refused,
    naming script.audio; with the keys or the audio gone it is fine."""
    from servoface.controller.script import load_script
    from servoface.controller.speech.errors import SpeechError
    from servoface.controller.speech.script_play import prepare

    script = _say_out(tmp_path, "Bob bought a big blue balloon.")
    path = tmp_path / "speech.toml"
    path.write_text(path.read_text() + '\n[[play]]\nat_s = 3.0\nsay = "And hello."\n')
    with pytest.raises(SpeechError, match=r"script\.audio: the speech track has both say cues and mouth keys"):
        prepare(load_script(path))
    assert prepare(script).audio is not None  # the keys with their sound alone
    cue_only = parse_script('[script]\nface = "human"\n[[play]]\nat_s = 0.0\nsay = "Hi."\n', source="c.toml")
    assert len(prepare(cue_only).cues) == 1
