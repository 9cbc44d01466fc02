"""Shared pytest fixtures (add fixtures only; each part keeps its own block)."""

# ---- hardware fixtures (driver engineer): the emulated chain, the bus over it, a configured driver ----
# Reusable for your own hardware-in-the-loop tests: mark a test `@pytest.mark.hardware` and set
# SERVOFACE_PORT=/dev/ttyUSB0 (SERVOFACE_BAUD, SERVOFACE_IDS="1-6", SERVOFACE_MODEL) to run it against real
# servos; without SERVOFACE_PORT such a test is skipped with that reason. Unmarked tests use the emulator.
import os as _os

import pytest as _pytest

HW_IDS_DEFAULT = "1-4"


def _hw_ids() -> list[int]:
    from servoface.hardware.bus import ids_from_spec

    return ids_from_spec(_os.environ.get("SERVOFACE_IDS", HW_IDS_DEFAULT))


@_pytest.fixture
def servo_chain():  # type: ignore[no-untyped-def]
    """An emulated chain of 4 XL330-M288 (ids 1-4) at 1 Mbps, no wire time, real clock."""
    from servoface.hardware.emulator import ServoChain

    chain = ServoChain.create(ids=range(1, 5), model="XL330-M288", baud=1_000_000, wire_time=False)
    yield chain
    chain.close()


@_pytest.fixture
def dxl_bus(request):  # type: ignore[no-untyped-def]
    """A `DynamixelBus`: in-process over `servo_chain`, or the real port for `@pytest.mark.hardware` tests."""
    from servoface.hardware.bus import open_bus

    if request.node.get_closest_marker("hardware") is not None:
        port = _os.environ.get("SERVOFACE_PORT")
        if not port:
            _pytest.skip("real-servo test: set SERVOFACE_PORT=/dev/ttyUSB0 (and SERVOFACE_IDS) to run it")
        bus = open_bus("dynamixel", port=port, baud=int(_os.environ.get("SERVOFACE_BAUD", "1000000")))
    else:
        bus = open_bus("dynamixel", port=request.getfixturevalue("servo_chain"))
    yield bus
    bus.close()


@_pytest.fixture
def servo_specs(request):  # type: ignore[no-untyped-def]
    """One `ServoSpec` per servo (limits 1024..3072, RDT 0) for the chain or SERVOFACE_IDS."""
    from servoface.hardware.servo_config import ServoSpec

    if request.node.get_closest_marker("hardware") is not None:
        ids, model = _hw_ids(), _os.environ.get("SERVOFACE_MODEL", "XL330-M288")
    else:
        chain = request.getfixturevalue("servo_chain")
        ids, model = chain.ids, "XL330-M288"
    return [ServoSpec(i, model, role=f"servo_{i}", min_position_tick=1024, max_position_tick=3072) for i in ids]


@_pytest.fixture
def driver(dxl_bus, servo_specs):  # type: ignore[no-untyped-def]
    """A configured `Driver` (torque off) on `dxl_bus`; torque is switched off again at teardown."""
    from servoface.hardware.driver import Driver

    drv = Driver(dxl_bus, servo_specs)
    drv.configure()
    yield drv
    try:
        drv.torque_off()
    except Exception:  # noqa: BLE001 - teardown of a test that may have broken the bus on purpose
        pass


# ---- calibration fixtures (calibration engineer): the built-in heads' shipped calibration files ----
# `calibration` is a `calibration.HeadCalibration` (role -> curve, limits, neutral). For your own head, load
# yours with `calibration.load_calibration(path)` in a fixture of the same shape.
@_pytest.fixture
def calibration():  # type: ignore[no-untyped-def]
    """The built-in human head's `HeadCalibration` (sim/heads/human/calibration.json)."""
    from pathlib import Path

    from servoface.calibration.fileformat import load_calibration

    return load_calibration(Path(__file__).resolve().parents[1] / "sim" / "heads" / "human" / "calibration.json")


@_pytest.fixture
def dog_calibration():  # type: ignore[no-untyped-def]
    """The built-in dog head's `HeadCalibration` (sim/heads/dog/calibration.json)."""
    from pathlib import Path

    from servoface.calibration.fileformat import load_calibration

    return load_calibration(Path(__file__).resolve().parents[1] / "sim" / "heads" / "dog" / "calibration.json")


# ---- head fixtures (heads engineer): the built-in heads, loaded once per process (cached by load_head) ----
@_pytest.fixture
def head():  # type: ignore[no-untyped-def]
    """The built-in humanoid head (`servoface.sim.heads.load_head("human")`); treat it as read-only."""
    from servoface.sim.heads import load_head

    return load_head("human")


@_pytest.fixture
def dog_head():  # type: ignore[no-untyped-def]
    """The built-in dog head (`servoface.sim.heads.load_head("dog")`); treat it as read-only."""
    from servoface.sim.heads import load_head

    return load_head("dog")
