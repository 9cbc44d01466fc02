"""The pytest plugin (entry point ``servoface`` in ``pytest11``): options, markers and fixtures.

Installed with servoface, so any project that depends on it gets the fixtures with no conftest of its
own; a fixture of the same name in your conftest wins. Disable with ``-p no:servoface``. Only pytest and
the standard library are imported here; servoface's own modules load when a fixture is used.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

HARDWARE_MARKER = (
    "hardware(emulate=False): runs on real servos given by --servoface-port /dev/ttyUSB0 (or SERVOFACE_PORT; "
    "with --servoface-ids/--servoface-head/--servoface-baud); without a port it is skipped, or run on the "
    "emulator with emulate=True"
)
SERVOFACE_MARKER = (
    "servoface(head=, servos=, model=, transport='inprocess'|'pty', clock='real'|'manual', wire_time=, baud=, "
    "goal_limit=, rate_hz=, limits_tick=, faults=): the emulated chain of this test"
)
NO_PORT = (
    "real-servo test: give --servoface-port /dev/ttyUSB0 (or set SERVOFACE_PORT), with --servoface-head or "
    "--servoface-ids, to run it"
)


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("servoface", "servoface hardware-in-the-loop (real servos for @pytest.mark.hardware)")
    group.addoption(
        "--servoface-port", dest="servoface_port", default=None, help="serial port of real servos (env SERVOFACE_PORT)"
    )
    group.addoption(
        "--servoface-baud",
        dest="servoface_baud",
        default=None,
        help="their baud rate, default 1000000 (SERVOFACE_BAUD)",
    )
    group.addoption("--servoface-ids", dest="servoface_ids", default=None, help="their ids, e.g. 1-4,7 (SERVOFACE_IDS)")
    group.addoption(
        "--servoface-head",
        dest="servoface_head",
        default=None,
        help="their head: built-in name or profile folder (SERVOFACE_HEAD)",
    )
    group.addoption(
        "--servoface-model",
        dest="servoface_model",
        default=None,
        help="model of --servoface-ids, default XL330-M288 (SERVOFACE_MODEL)",
    )
    for key, what in (
        ("head", "built-in head name or profile folder of the emulated chain"),
        ("servos", "explicit emulated servos: '1-4' or '1:XL330-M288,2:XL430-W250'"),
        ("model", "model of an id-only servo list (default XL330-M288)"),
        ("transport", "inprocess (default) or pty (served by another process)"),
        ("clock", "real (default) or manual"),
    ):
        parser.addini(f"servoface_{key}", what, default="")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", HARDWARE_MARKER)
    config.addinivalue_line("markers", SERVOFACE_MARKER)


def _real_rig(config: pytest.Config) -> Any:
    from servoface.testing.real_servos import RealRig

    return RealRig.from_options(config.option)


def pytest_report_header(config: pytest.Config) -> str:
    try:
        rig = _real_rig(config)
    except Exception as err:  # noqa: BLE001 - a bad option is reported where it is used, with its name
        return f"servoface: {err}"
    if rig.port:
        return f"servoface: @pytest.mark.hardware tests run on {rig.describe()}"
    return "servoface: @pytest.mark.hardware tests need --servoface-port (or SERVOFACE_PORT); the rest use the emulator"


def pytest_runtest_setup(item: pytest.Item) -> None:
    marker = item.get_closest_marker("hardware")
    if marker is not None and not _real_rig(item.config).port and not marker.kwargs.get("emulate", False):
        pytest.skip(NO_PORT)


def _on_hardware(request: pytest.FixtureRequest) -> bool:
    return request.node.get_closest_marker("hardware") is not None and bool(_real_rig(request.config).port)


# ---- configuration ----------------------------------------------------------------------------------------
@pytest.fixture
def servoface_config(request: pytest.FixtureRequest) -> Any:
    """The resolved `servoface.testing.ServofaceConfig` of this test (marker over ini over defaults).
    On real servos, --servoface-head / --servoface-ids describe the bench and win."""
    from servoface.testing.config import ServofaceConfig, resolve

    marker = request.node.get_closest_marker("servoface")
    ini = {k: str(request.config.getini(f"servoface_{k}")) for k in ("head", "servos", "model", "transport", "clock")}
    config: ServofaceConfig = resolve(
        dict(marker.kwargs) if marker else {}, ini, wants_face="face" in request.fixturenames
    )
    if _on_hardware(request):
        from dataclasses import replace

        from servoface.testing.config import DEFAULT_MODEL, parse_servos

        rig = _real_rig(request.config)
        if rig.head:
            config = replace(config, head=rig.head, servos=None)
        elif rig.ids:
            servos = parse_servos(rig.ids, rig.model or DEFAULT_MODEL, "--servoface-ids / SERVOFACE_IDS")
            config = replace(config, head=None, servos=servos)
        config = replace(config, baud=rig.baud)
    return config


@pytest.fixture
def servoface_rig(servoface_config: Any) -> Any:
    """The servos under test (`servoface.testing.rig.Rig`): specs, and the head and calibration if any."""
    from servoface.testing.rig import build_rig

    return build_rig(servoface_config)


@pytest.fixture
def head(servoface_config: Any) -> Any:
    """The head under test (`servoface.sim.head.Head`): the configured one, else the built-in human head.
    Read-only (load_head caches it per process)."""
    from servoface.testing.rig import load_head_and_calibration

    return load_head_and_calibration(servoface_config.head or "human")[0]


@pytest.fixture
def calibration(servoface_config: Any) -> Any:
    """The `HeadCalibration` the head under test's profile names (built-in human unless configured)."""
    from servoface.testing.rig import load_head_and_calibration

    return load_head_and_calibration(servoface_config.head or "human")[1]


@pytest.fixture
def servo_specs(servoface_rig: Any) -> list[Any]:
    """One `ServoSpec` per servo: a head's from its calibration, else the explicit list (ids 1-4,
    XL330-M288, limits 1024..3072 unless configured)."""
    return list(servoface_rig.specs)


# ---- the chain and what talks to it ---------------------------------------------------------------------
def _open_chain(spec: Any, transport: str) -> Any:
    from servoface.testing.chains import LocalChain
    from servoface.testing.served_chain import ServedChain

    return ServedChain(spec) if transport == "pty" else LocalChain(spec)


@pytest.fixture
def servo_chain(request: pytest.FixtureRequest, servoface_config: Any, servoface_rig: Any) -> Iterator[Any]:
    """The emulated chain (`LocalChain` in-process, or `ServedChain` on a pty of another process), with the
    configured faults scheduled. On real servos a test that needs it is skipped (faults, clock and hand moves
    are the emulator's)."""
    if _on_hardware(request):
        pytest.skip("this test drives the emulator (servo_chain); it cannot run on real servos")
    chain = _open_chain(servoface_rig.chain_spec(servoface_config), servoface_config.transport)
    try:
        for plan in servoface_config.faults:
            chain.inject(plan.servo_id, plan.kind, at_s=plan.after_s, duration_s=plan.duration_s, **plan.options)
        yield chain
    finally:
        chain.close()


@pytest.fixture
def make_servo_chain(servoface_config: Any) -> Iterator[Callable[..., Any]]:
    """A factory for more chains: ``make_servo_chain(head="dog", transport="pty", clock="manual")`` (the
    marker's arguments); every chain it made is closed at teardown."""
    from servoface.testing.config import resolve
    from servoface.testing.rig import build_rig

    made: list[Any] = []

    def make(**kwargs: Any) -> Any:
        config = resolve(kwargs, {}, wants_face=False)
        chain = _open_chain(build_rig(config).chain_spec(config), config.transport)
        made.append(chain)
        return chain

    yield make
    for chain in made:
        chain.close()


@pytest.fixture
def servo_target(request: pytest.FixtureRequest, servoface_config: Any, servoface_rig: Any) -> Any:
    """What the test's code talks to: the emulated chain, or `RealServos` on the bench."""
    if _on_hardware(request):
        from servoface.testing.real_servos import RealServos

        rig = _real_rig(request.config)
        return RealServos(rig.port, servoface_config.baud, [s.servo_id for s in servoface_rig.specs])
    return request.getfixturevalue("servo_chain")


@pytest.fixture
def servo_port(servo_target: Any) -> Any:
    """The port for the code under test: a device path (pty of the served chain, or the real port), or, for
    an in-process chain, the chain object that servoface's ``open_bus``/``Face.open(port=...)`` take."""
    return servo_target.port


@pytest.fixture
def dxl_bus(servo_target: Any, servoface_config: Any) -> Iterator[Any]:
    """A `DynamixelBus` (stock dynamixel_sdk) on ``servo_port``."""
    from servoface.hardware.bus import open_bus

    bus = open_bus("dynamixel", port=servo_target.port, baud=servoface_config.baud)
    if getattr(servo_target, "transport", "") == "real":
        servo_target.bus = bus
    yield bus
    bus.close()


@pytest.fixture
def driver(dxl_bus: Any, servo_specs: list[Any], servoface_config: Any) -> Iterator[Any]:
    """A configured `Driver` (torque off) on ``dxl_bus``; torque is switched off again at teardown.

    On a manual clock the Bus Watchdog is left off: ``servo_chain.advance(0.5)`` is half a second without a
    packet, and an armed watchdog would stop the servos then — as real ones do when the host goes quiet."""
    from servoface.hardware.driver import Driver
    from servoface.hardware.fault_policy import FaultPolicy

    manual = getattr(servoface_config, "clock", "real") == "manual"
    drv = Driver(dxl_bus, servo_specs, policy=FaultPolicy(watchdog_s=0) if manual else None)
    drv.configure()
    yield drv
    try:
        drv.torque_off()
    except Exception:  # noqa: BLE001 - teardown of a test that may have broken the bus on purpose
        pass


@pytest.fixture
def face(servo_target: Any, servoface_config: Any, servoface_rig: Any) -> Iterator[Any]:
    """A `Face` (the whole pipeline: muscle model, calibration, twin gate, driver) on ``servo_port``,
    torque on, pinned where the servos stand; closed (torque off, no easing) at teardown."""
    from servoface.controller.face import Face

    if servoface_rig.head is None:
        pytest.fail("the face fixture needs a head: configure head= (servoface marker or ini), not servos=")
    the_face = Face.open(
        servoface_rig.head, port=servo_target.port, baud=servoface_config.baud, calibration=servoface_rig.calibration
    )
    yield the_face
    the_face.close(ease_s=0.0)


@pytest.fixture
def wire_limits(servoface_config: Any, servoface_rig: Any) -> Any:
    """`WireLimits` the wire checks use: a head's calibrated limits, else the servo specs' limits; the gate's
    speed/acceleration caps at the config's ``rate_hz``."""
    return servoface_rig.limits(servoface_config)


@pytest.fixture
def servo_wire(servo_target: Any, wire_limits: Any) -> Any:
    """`WireChecker`: assertions on what reached the servos (``assert_safe``, ``assert_torque_off``,
    ``assert_matches_twin``, ...), each failure naming the servo."""
    from servoface.testing.checker import WireChecker

    return WireChecker(servo_target, wire_limits)
