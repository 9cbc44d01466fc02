"""The Python API and the file formats turn any malformed value into the package's typed error naming the
field — never another exception. Many cheap examples per entry point (>= 10^4 each, bounded time): the
motion itself is not run here (on an offline face, `Face._perform` submits each command to a head service
that was never started: the Face's and the service's checks run, then the service refuses to queue it);
what a valid input does on the wire is checked by the emulator properties
(tests/integration/test_unsafe_script.py, tests/fuzz/test_fuzz_wire.py)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from servoface.calibration import CalibrationError
from servoface.calibration.builtin import builtin_calibration
from servoface.calibration.fileformat import calibration_from_dict, calibration_to_dict, load_calibration
from servoface.controller.errors import ControllerError
from servoface.controller.face import Face
from servoface.controller.performance import Performance
from servoface.controller.service import HeadService, ServiceClosedError
from servoface.sim.errors import SimError

from tests.calibration.helpers import small_specs
from tests.fuzz.strategies import mutated, values, weird_text

N = int(os.environ.get("SERVOFACE_FUZZ_EXAMPLES", "10000"))  # >= 10^4 per entry point in CI
FAST = settings(max_examples=N, deadline=None, suppress_health_check=list(HealthCheck), database=None)


@pytest.fixture(scope="module")
def face() -> Face:
    f = Face.offline("human")
    service = HeadService(f.head, f.pipeline, start=False)  # validates every command, queues none

    def record(submit: Callable[[HeadService], Any], duration_s: float) -> Performance:
        try:
            submit(service)
        except ServiceClosedError:
            pass  # every check passed; only the unstarted service refused it
        return Performance()

    f._perform = record  # type: ignore[method-assign]
    return f


aus_maps = st.one_of(
    st.dictionaries(weird_text, values, max_size=4),
    st.dictionaries(st.sampled_from(["AU1", "AU12", "AU26", "AU45", "AU61"]), values, max_size=4),
    values,
)
seconds = st.one_of(values, st.floats(0, 5))


def _typed(fn: Any, *args: Any, **kw: Any) -> None:
    try:
        fn(*args, **kw)
    except (ControllerError, SimError, CalibrationError) as err:
        assert str(err)  # a message
        assert "\x1b" not in repr(str(err)).replace("\\x1b", "")


@FAST
@given(aus_maps, seconds, seconds)
def test_set_aus(face: Face, aus: Any, transition_s: Any, hold_s: Any) -> None:
    _typed(face.set_aus, aus, transition_s=transition_s, hold_s=hold_s)


@FAST
@given(st.one_of(values, st.sampled_from(["happiness", "surprise"])), values, seconds, seconds)
def test_express(face: Face, name: Any, intensity: Any, transition_s: Any, hold_s: Any) -> None:
    _typed(face.express, name, intensity=intensity, transition_s=transition_s, hold_s=hold_s)


@FAST
@given(st.one_of(values, st.tuples(values, values, values)), seconds)
def test_look_at(face: Face, point: Any, transition_s: Any) -> None:
    _typed(face.look_at, point, transition_s=transition_s)


@pytest.mark.parametrize("bad", ["AU１２", " AU12", "AU12\n", "AU12 ", "AU١٢", "AU\u200b12"])
def test_names_are_matched_exactly_ascii_digits_only(face: Face, bad: str) -> None:
    with pytest.raises(ControllerError, match="not an AU name"):
        face.set_aus({bad: 0.5})


def test_nfc_names_are_normalised(face: Face) -> None:
    import unicodedata

    decomposed = unicodedata.normalize("NFD", "AU12")  # plain ASCII: NFC leaves it as is
    face.set_aus({decomposed: 0.5})


# -- calibration files ---------------------------------------------------------------------------------

_BASE_CAL = calibration_to_dict(builtin_calibration("small", small_specs()[:2]))  # a joint and an anchor: cheap


@FAST
@given(mutated(_BASE_CAL))
def test_calibration_dicts(data: Any) -> None:
    try:
        calibration_from_dict(data)
    except CalibrationError as err:
        assert str(err)


@pytest.mark.parametrize("depth", [1000, 100_000])
def test_deeply_nested_calibration_json(tmp_path: Path, depth: int) -> None:
    p = tmp_path / "cal.json"
    p.write_text("[" * depth + "]" * depth)
    with pytest.raises(CalibrationError):
        load_calibration(p)
    p.write_text('{"schema_version": 1, "servos": ' + "[" * depth + "]" * depth + "}")
    with pytest.raises(CalibrationError):
        load_calibration(p)
