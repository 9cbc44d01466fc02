"""Scripts and head profiles: any malformed value is the package's typed error naming the field (never
another exception, never a script that loads but cripples the loop)."""

from __future__ import annotations

import copy
import os
import tomllib
from pathlib import Path
from typing import Any

from hypothesis import given
from hypothesis import strategies as st
from servoface.controller.errors import ControllerError, ScriptError
from servoface.controller.script import _Builder, parse_script
from servoface.controller.script_fields import Reader
from servoface.sim.errors import SimError

from tests.fuzz.strategies import fuzz_settings, mutated

N = int(os.environ.get("SERVOFACE_FUZZ_EXAMPLES", "10000"))
FAST = fuzz_settings(N)
ROOT = Path(__file__).resolve().parents[2]

HUMAN = tomllib.loads(
    """
[script]
face = "human"
end_s = 2.0
[poses]
smile = { AU6 = 0.3, AU12 = 0.6 }
[expressions.smile]
duration_s = 0.8
movements = [{ pose = "smile", percent = 60, easing = "min_jerk" }, { pose = "smile", percent = 40 }]
[[play]]
at_s = 0.1
expression = "smile"
[[play]]
at_s = 1.0
track = "gesture"
expression = "smile"
[blink]
mean_interval_s = 4.0
[idle]
head_amplitude = 0.02
"""
)
DOG = tomllib.loads(
    """
[script]
face = "dog"
[expressions.sniff]
events = ["AU1", { au = "AU7", value = -0.5 }]
repeat = 2
timing = { gap_s = 0.2 }
[[play]]
at_s = 0.0
expression = "sniff"
"""
)


def _build(data: Any) -> None:
    try:
        _Builder(Reader("<fuzz>", ""), None).build(data)
    except ScriptError as err:
        assert str(err)
    except ControllerError as err:  # FrameError / TimelineError from a deeper layer: typed, named
        assert str(err)


@FAST
@given(mutated(HUMAN, max_depth=300))  # deeper cannot come out of TOML (tomllib refuses)
def test_human_script_tables(data: Any) -> None:
    _build(data)


@FAST
@given(mutated(DOG, max_depth=300))
def test_dog_script_tables(data: Any) -> None:
    _build(data)


@FAST
@given(st.text(max_size=200))
def test_script_text(text: str) -> None:
    try:
        parse_script("[script]\nface = 'human'\n" + text)
    except ControllerError as err:
        assert str(err)


def test_deeply_nested_script_text() -> None:
    for text in ("x = " + "[" * 5000 + "]" * 5000, "x = " + "{a = " * 3000 + "1" + "}" * 3000):
        try:
            parse_script("[script]\nface = 'human'\n" + text)
        except ScriptError as err:
            assert str(err)


PROFILE = tomllib.loads((ROOT / "sim/heads/human/head.toml").read_text())
PROFILE_FOLDER = ROOT / "sim/heads/human"
PROFILE_BUILT_N = max(10, N // 250)  # a valid profile that builds fully binds its skin (~0.3 s): a few here


def _profile(data: Any, bind_skin: bool) -> None:
    from servoface.sim.profile import _Reader, build_checked

    try:
        build_checked(_Reader(PROFILE_FOLDER / "head.toml"), data, PROFILE_FOLDER, bind_skin=bind_skin)
    except SimError as err:
        assert str(err)


@fuzz_settings(N)
@given(mutated(PROFILE, max_depth=300, root=False))
def test_head_profiles_parse_and_validate(data: Any) -> None:
    """Every field parsed and checked, meshes loaded; only the skin's bind weights (a computation that
    cannot fail) are skipped (``bind_skin=False``): 10^4 profiles in bounded time."""
    _profile(data, bind_skin=False)


@fuzz_settings(PROFILE_BUILT_N)
@given(mutated(PROFILE, max_depth=300, root=False))
def test_head_profiles_build_fully(data: Any) -> None:
    _profile(data, bind_skin=True)


def test_validation_only_accepts_and_refuses_what_a_full_build_does() -> None:
    """The seam the 10^4 profiles go through is the full build minus the bind weights: the shipped profile
    passes both ways with the same head, and a broken field fails both ways with the same message."""
    from servoface.sim.errors import HeadProfileError
    from servoface.sim.profile import _Reader, build_checked

    file = PROFILE_FOLDER / "head.toml"
    full = build_checked(_Reader(file), PROFILE, PROFILE_FOLDER)
    quick = build_checked(_Reader(file), PROFILE, PROFILE_FOLDER, bind_skin=False)
    assert full.roles == quick.roles and full.skin.joint_names == quick.skin.joint_names
    assert full.skin.weights.shape == quick.skin.weights.shape
    broken = {**PROFILE, "actuator": [{**PROFILE["actuator"][0], "servo": "one"}, *PROFILE["actuator"][1:]]}
    messages = []
    for bind in (True, False):
        try:
            build_checked(_Reader(file), broken, PROFILE_FOLDER, bind_skin=bind)
        except HeadProfileError as err:
            messages.append(str(err))
    assert len(messages) == 2 and messages[0] == messages[1] and "actuator[0]" in messages[0]


_PRISTINE = {"human": copy.deepcopy(HUMAN), "dog": copy.deepcopy(DOG), "profile": copy.deepcopy(PROFILE)}


def test_the_base_documents_were_never_changed() -> None:
    """`mutated` shares all but the path it changes with the base: nothing above may have written into it."""
    assert (HUMAN, DOG, PROFILE) == (_PRISTINE["human"], _PRISTINE["dog"], _PRISTINE["profile"])
