"""servoface's hardware-in-the-loop test kit, installed with servoface and registered as a pytest plugin.

Any project that depends on servoface gets these fixtures with no conftest of its own (see the README
section "Test your own code against the emulator"):

- ``servo_chain``: an emulated chain (a head's, or an explicit servo list), in-process or on a pty served
  by another process, real or manual clock, faults scriptable in chain time (``servo_chain.inject``);
- ``servo_port`` (what your code opens), ``dxl_bus``, ``driver``, ``face``, ``head``, ``calibration``,
  ``servo_specs``, ``make_servo_chain``;
- ``servo_wire``: assertions decoded from what the emulator received (goals inside the calibrated limits
  and the gate's speed/acceleration caps, no goal while torque was off, torque state and final positions
  at the end), each failure naming the servo;
- ``@pytest.mark.hardware``: the same test on real servos with ``--servoface-port /dev/ttyUSB0``.

Configure a test with ``@pytest.mark.servoface(head="dog", transport="pty", clock="manual", ...)`` or
``servoface_*`` ini options. Names are imported lazily so that loading the plugin stays cheap.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_EXPORTS = {
    "ChainSpec": "servoface.testing.chains",
    "LocalChain": "servoface.testing.chains",
    "ServedChain": "servoface.testing.served_chain",
    "RecordingChain": "servoface.testing.recording_chain",
    "ServofaceConfig": "servoface.testing.config",
    "FaultPlan": "servoface.testing.config",
    "WireChecker": "servoface.testing.checker",
    "WireLimits": "servoface.testing.limits",
    "ServoLimit": "servoface.testing.limits",
    "WireRecord": "servoface.testing.record",
    "GoalWrite": "servoface.testing.record",
    "TorqueWrite": "servoface.testing.record",
    "ServoEnd": "servoface.testing.record",
    "WireNotObservedWarning": "servoface.testing.wire",
    "RealServos": "servoface.testing.real_servos",
    "TestKitError": "servoface.testing.errors",
    "TestKitConfigError": "servoface.testing.errors",
    "ServedChainError": "servoface.testing.errors",
    "load_head_and_calibration": "servoface.testing.rig",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'servoface.testing' has no attribute {name!r}")
    return getattr(import_module(module), name)
