"""TOML scripts: the examples load and play as written; every error names file, key path and line."""

from __future__ import annotations

from pathlib import Path

import pytest
from servoface.controller.errors import ScriptError
from servoface.controller.script import SCRIPTS_DIR, example_scripts, load_script, parse_script

MINIMAL = """
[script]
face = "human"

[poses]
smile = { AU12 = 0.8 }

[expressions.smile]
duration_s = 1.0
movements = [{ pose = "smile", percent = 100 }]

[[play]]
at_s = 0.5
expression = "smile"
"""


def test_examples_exist_and_load() -> None:
    names = {p.name for p in example_scripts()}
    assert {"human_performance.toml", "dog_performance.toml", "unsafe_pose.toml"} <= names
    for path in example_scripts():
        script = load_script(path)
        assert script.end_s > 0
        for k in range(int(script.end_s * 10) + 1):  # every frame of every example is a valid frame
            script.sample(k / 10)


def test_human_performance_plays_as_written() -> None:
    s = load_script(SCRIPTS_DIR / "human_performance.toml")
    assert s.face_type == "human" and s.end_s == 14.0
    assert s.timeline.layer_names == ("face", "gesture", "gaze", "blink", "idle")
    assert s.sample(0.9).get("AU12") == 0.0  # neutral before the smile
    assert s.sample(1.0 + 0.56).get("AU12") == pytest.approx(0.8)  # smile onset done (35 % of 1.6 s)
    assert s.sample(2.6 + 0.2).get("AU1") == pytest.approx(0.85)  # surprise starts from the smile
    assert s.sample(6.0 + 0.12 + 0.1).get("AU2") == pytest.approx(0.7)  # brow flash at apex
    thinking = s.sample(9.5)
    assert thinking.get("AU4") == pytest.approx(0.35)
    assert thinking.get("AU62") > 0 and thinking.get("AU63") > 0  # looking up to the right
    blinks = [k / 100 for k in range(1400) if s.sample(k / 100).get("AU45") > 0.9]
    assert blinks, "blinks happen"


def test_dog_performance_runs_the_recipes_in_order() -> None:
    s = load_script(SCRIPTS_DIR / "dog_performance.toml")
    assert s.face_type == "dog"
    clip = s.clips["anger"]
    firsts = {au: moves[0][0] for au, moves in clip.onsets().items() if moves}  # type: ignore[union-attr]
    assert sorted(firsts, key=firsts.__getitem__) == ["AU14", "AU4", "AU1", "AU2", "AU5", "AU7"]
    assert any(s.sample(k / 20).get("AU3") > 0 for k in range(400))  # sniffing happens
    assert s.sample(s.end_s).get("AU7") == pytest.approx(0.0)  # anger released


def test_unsafe_script_asks_for_the_clash_the_gate_must_clip() -> None:
    s = load_script(SCRIPTS_DIR / "unsafe_pose.toml")
    apex = s.sample(0.2 + 0.03)
    assert apex.get("AU12L") == 1.0 and apex.get("AU15L") == 1.0
    assert apex.get("AU27") == 1.0 and apex.get("AU51") == 1.0 and apex.get("AU53") == 1.0
    assert s.sample(0.2).get("AU12L") == 0.0  # from neutral to full in 30 ms


def test_alternative_forms_keyframes_envelope_from_and_blend() -> None:
    text = """
[script]
face = "human"
initial = { AU12 = 0.3 }

[expressions.talk]
keyframes = [
  { t_s = 0.1, pose = { AU26 = 0.4 }, easing = "min_jerk" },
  { t_s = 0.2, pose = {} },
]

[expressions.flash]
pose = { AU1 = 0.6 }
onset_s = 0.1
apex_s = 0.1
offset_s = 0.1
easing = "linear"

[[play]]
at_s = 1.0
track = "speech"
sequence = ["talk", "talk"]

[[play]]
at_s = 1.0
expression = "flash"
from = { AU4 = 0.2 }

[blend]
rules = { AU26 = "override" }
priority = ["speech", "face"]
"""
    s = parse_script(text)
    assert s.sample(0.0).get("AU12") == pytest.approx(0.3)
    assert s.sample(1.1).get("AU26") == pytest.approx(0.4)
    assert s.sample(1.25).get("AU26") == pytest.approx(0.4 * 0.5)  # second 'talk' half way up (min-jerk)
    assert s.sample(1.05).get("AU4") == pytest.approx(0.1)  # started from the explicit 'from' pose
    assert s.end_s == pytest.approx(1.4)


def err(text: str, source: str = "perf.toml") -> ScriptError:
    with pytest.raises(ScriptError) as info:
        parse_script(text, source=source)
    return info.value


def test_toml_syntax_error_carries_the_line() -> None:
    e = err('[script]\nface = "human"\n\n[poses]\nsmile = { AU12 = 0.8\n')
    assert str(e).startswith("perf.toml:5: TOML syntax error")
    assert e.line == 5  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("text", "needle", "line"),
    [
        ('[script]\nface = "cat"\n', "script.face: expected 'human' or 'dog', got 'cat'", 2),
        ("[poses]\n", "script: missing; this key is required", None),
        ('[script]\nface = "human"\ncolour = 1\n', "script.colour: unknown key; expected one of", 3),
        (
            MINIMAL.replace("AU12 = 0.8", "AU12 = 1.8"),
            "poses.smile.AU12: FACS intensity 1.8 is out of range",
            6,
        ),
        (
            MINIMAL.replace("AU12 = 0.8", "AU3 = 0.8"),
            "poses.smile.AU3: AU3 is not an AU of the human face",
            6,
        ),
        (MINIMAL.replace('pose = "smile"', 'pose = "grin"'), "movements[0].pose: unknown pose 'grin'", 10),
        (MINIMAL.replace("percent = 100", "percent = 90"), "shares must sum to 1 (100 %), got 0.9", None),
        (MINIMAL.replace("percent = 100", "percent = 100, share = 1.0"), "expected exactly one of share", 10),
        (
            MINIMAL.replace('expression = "smile"', 'expression = "smirk"'),
            "play[0].expression: unknown expression 'smirk'",
            14,
        ),
        (
            MINIMAL.replace("at_s = 0.5", "at_s = -1"),
            "play[0].at_s: expected a start time in seconds >= 0",
            13,
        ),
        (
            MINIMAL + '\n[[play]]\nat_s = 1\ntrack = "blink"\nexpression = "smile"\n',
            "play[1].track: expected a track name",
            18,
        ),
        (
            MINIMAL + "\n[[gaze]]\nat_s = 1\nlook_at_mm = [1, 2]\n",
            "gaze[0].look_at_mm: expected [x, y, z] in mm",
            18,
        ),
        (MINIMAL + "\n[[gaze]]\nat_s = 1\n", "gaze[0]: expected exactly one of look_at_mm", 16),
        (
            MINIMAL + "\n[blink]\nmean_interval_s = 0.1\n",
            "blink.mean_interval_s: 0.1 s is below the 0.5 s a head can follow",
            None,
        ),
        (MINIMAL + "\n[blink]\nrate = 3\n", "blink.rate: unknown key", 17),
        (MINIMAL + '\n[blend]\nrules = { AU12 = "average" }\n', "unknown blend rule 'average'", 17),
        (
            MINIMAL.replace("movements = [", 'easing = "x"\nmovements = ['),
            "unknown key; expected one of: duration_s, movements",
            10,
        ),
        (
            MINIMAL.replace("percent = 100 }", 'percent = 100, easing = "bouncy" }'),
            "expressions.smile.movements[0].easing: unknown easing 'bouncy'",
            10,
        ),
        (
            MINIMAL + '\n[expressions.growl]\nevents = ["AU14"]\n',
            "expressions.growl: DFACS events and recipes are for the dog face",
            16,
        ),
        (
            '[script]\nface = "dog"\n[expressions.a]\nevents = ["AU14", "AU7c"]\n',
            "expressions.a.events[1]: 'AU7c' is not an event",
            4,
        ),
        (
            '[script]\nface = "dog"\n[expressions.a]\nevents = ["AU14"]\ntiming = { move_s = -1 }\n',
            "expressions.a.timing.move_s: expected move_s >= 0",
            5,
        ),
    ],
)
def test_script_errors_name_file_key_path_and_line(text: str, needle: str, line: int | None) -> None:
    e = err(text)
    assert needle in str(e), str(e)
    assert str(e).startswith("perf.toml")
    if line is not None:
        assert e.line == line, str(e)  # type: ignore[attr-defined]


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ScriptError, match=r"nope\.toml: cannot read script"):
        load_script(tmp_path / "nope.toml")


def test_allowed_names_come_from_the_caller() -> None:
    with pytest.raises(ScriptError, match="poses.smile.AU12: AU12 is not an AU of the human face; expected one of AU6"):
        parse_script(MINIMAL, allowed=frozenset({"AU6"}))


def test_library_expressions_play_from_a_script() -> None:
    human = parse_script(
        '[script]\nface = "human"\n[expressions.joy]\nlibrary = "happiness"\n'
        "onset_s = 0.2\napex_s = 1.0\noffset_s = 0.3\n"
        '[[play]]\nat_s = 0\nexpression = "joy"\n[[play]]\nat_s = 3\nlibrary = "surprise"\n'
    )
    assert human.sample(0.7).get("AU12") > 0.5
    assert human.sample(1.5).get("AU12") == pytest.approx(0.0)
    assert human.sample(3.0 + 0.4 + 0.5).get("AU1") > 0.3
    dog = parse_script('[script]\nface = "dog"\n[[play]]\nat_s = 0\nlibrary = "fear"\n')
    assert dog.sample(1.2).get("AU5") < 0  # ears back
    assert dog.sample(dog.end_s).get("AU5") == pytest.approx(0.0)  # released
    e = err('[script]\nface = "human"\n[[play]]\nat_s = 0\nlibrary = "glee"\n')
    assert "play[0].library: expression 'glee' is not in the human library; known:" in str(e)
    assert e.line == 5  # type: ignore[attr-defined]


def test_gaze_setup_and_end_time_include_gaze_shifts() -> None:
    text = (
        '[script]\nface = "human"\n[[gaze]]\nat_s = 2.0\nlook_at_mm = [800, 0, 600]\n'
        "[gaze_setup]\neye_center_mm = [0, 70, 60]\nhead_move_s = 0.8\n"
    )
    s = parse_script(text)
    assert s.end_s == pytest.approx(2.8)
    layer = s.timeline.layer("gaze")
    assert layer.config.eye_center_mm == (0.0, 70.0, 60.0)  # type: ignore[attr-defined]
    assert s.sample(2.8).get("AU51") > 0
    e = err(text.replace("head_move_s = 0.8", "head_move_s = 0"))
    assert "gaze_setup.head_move_s: expected a positive number" in str(e) and e.line == 8  # type: ignore[attr-defined]


# -- the speech cue (controller/script_say.py) ---------------------------------------------------------
SAY = """
[script]
face = "human"

[[play]]
at_s = 0.0
library = "happiness"

[[play]]
at_s = 0.5
say = "Hello, nice to meet you."
"""


def test_a_say_cue_plays_the_lip_sync_visemes_on_the_speech_track() -> None:
    from servoface.controller.script import parse_script

    script = parse_script(SAY, source="say.toml")
    assert script.timeline.layer("speech") is not None
    before = script.timeline.sample_aus(0.3)
    talking = [script.timeline.sample_aus(0.5 + i * 0.05) for i in range(1, 30)]
    assert before.get("AU26", 0.0) == 0.0
    assert max(a.get("AU26", 0.0) for a in talking) > 0.3  # the jaw opens on the vowels
    assert min(a.get("AU25", 1.0) for a in talking) < 0.1  # ... and the lips close on the bilabial of "meet"
    assert all(a.get("AU12", 0.0) > 0.5 for a in talking[5:])  # the smile stays while it talks


def test_bad_say_cues_name_the_field() -> None:
    from servoface.controller.errors import ScriptError
    from servoface.controller.script import parse_script

    head = '[script]\nface = "human"\n[[play]]\nat_s = 0.0\n'
    for body, path in (
        ('say = ""', "play[0].say"),
        ("say = 3", "play[0].say"),
        ('say = "hi"\nvoice = "../x"', "play[0].voice"),
        ('library = "happiness"\nvoice = "en"', "play[0].voice"),
        ('say = "hi"\nlibrary = "happiness"', "play[0]"),
    ):
        with pytest.raises(ScriptError) as err:
            parse_script(head + body, source="bad.toml")
        assert getattr(err.value, "key_path", None) == path, (body, str(err.value))
