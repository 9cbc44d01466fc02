"""Shared pytest fixtures (add fixtures only; each part keeps its own block).

servoface's own suite uses the test kit the way users do: ``servo_chain``, ``servo_port``, ``dxl_bus``,
``servo_specs``, ``driver``, ``face``, ``head``, ``calibration``, ``servo_wire``, ``make_servo_chain`` and the
``hardware`` marker come from the installed pytest plugin ``servoface.testing`` (pyproject.toml's ``pytest11``
entry point), not from this file. Real servos: ``pytest -m hardware --servoface-port /dev/ttyUSB0
--servoface-ids 1-4`` (or SERVOFACE_PORT / SERVOFACE_IDS); without a port those tests are skipped with that
reason. Only fixtures particular to this suite live here.
"""

import pytest as _pytest


# ---- calibration fixtures (calibration engineer): the built-in dog head's shipped calibration file ----
# `calibration` (the head under test's, built-in human unless configured) comes from the plugin.
@_pytest.fixture
def dog_calibration():  # type: ignore[no-untyped-def]
    """The built-in dog head's `HeadCalibration` (sim/heads/dog/calibration.json)."""
    from servoface.testing import load_head_and_calibration

    return load_head_and_calibration("dog")[1]


# ---- head fixtures (heads engineer): the built-in dog head, loaded once per process (cached by load_head) ----
# `head` (the head under test, built-in human unless configured) comes from the plugin.
@_pytest.fixture
def dog_head():  # type: ignore[no-untyped-def]
    """The built-in dog head (`servoface.sim.heads.load_head("dog")`); treat it as read-only."""
    from servoface.testing import load_head_and_calibration

    return load_head_and_calibration("dog")[0]


# ---- packaging fixtures: servoface's wheel in a fresh venv outside the repo, built once per session ----
@_pytest.fixture(scope="session")
def wheel_venv(tmp_path_factory):  # type: ignore[no-untyped-def]
    """(venv python, base folder, environment): the wheel is in base/dist, the venv in base/venv."""
    from tests.wheel_venv import build

    base = tmp_path_factory.mktemp("wheel")
    python, env = build(base)
    return python, base, env
