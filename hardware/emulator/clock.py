"""Clocks for the chain: real time (monotonic, so SDK timeouts behave) or a manual clock for tests."""

from __future__ import annotations

import time

from servoface.hardware.emulator.errors import EmulatorConfigError


class RealClock:
    """Seconds since the chain was created, from ``time.monotonic``."""

    manual = False

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def __call__(self) -> float:
        return time.monotonic() - self._t0

    def advance(self, dt_s: float) -> None:
        raise EmulatorConfigError("chain.advance() needs a manual clock: create the chain with clock='manual'")


class ManualClock:
    """A clock that moves only when told to (deterministic physics tests)."""

    manual = True

    def __init__(self, start_s: float = 0.0) -> None:
        self._t = float(start_s)

    def __call__(self) -> float:
        return self._t

    def advance(self, dt_s: float) -> None:
        if dt_s < 0:
            raise EmulatorConfigError(f"clock advance dt_s {dt_s}: expected >= 0 (time does not run backwards)")
        self._t += float(dt_s)

    def set(self, t_s: float) -> None:
        if t_s < self._t:
            raise EmulatorConfigError(f"clock set to {t_s} s: expected >= current {self._t} s")
        self._t = float(t_s)
