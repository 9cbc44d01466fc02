"""Scripts and head profiles: any malformed value is the package's typed error naming the field (never
another exception, never a script that loads but cripples the loop)."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from servoface.controller.errors import ControllerError, ScriptError
from servoface.controller.script import _Builder, parse_script
from servoface.controller.script_fields import Reader
from servoface.sim.errors import SimError

from tests.fuzz.strategies import mutated

N = int(os.environ.get("SERVOFACE_FUZZ_EXAMPLES", "10000"))
FAST = settings(max_examples=N, deadline=None, suppress_health_check=list(HealthCheck), database=None)
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
PROFILE_N = max(50, N // 20)  # a valid profile builds its meshes (~0.4 s): fewer examples here


@settings(max_examples=PROFILE_N, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(mutated(PROFILE, max_depth=300, root=False))
def test_head_profiles(data: Any) -> None:
    from servoface.sim.profile import _Reader
    from servoface.sim.profile import build_checked as build_profile

    folder = ROOT / "sim/heads/human"
    try:
        build_profile(_Reader(folder / "head.toml"), data, folder)
    except SimError as err:
        assert str(err)
