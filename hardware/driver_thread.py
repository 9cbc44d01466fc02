"""`DriverThread`: a background thread that owns the bus and runs `Driver.cycle` at a fixed rate.

Other threads call `submit_goals()` (validated at once in the caller's thread; latest frame wins) and
`snapshot()`; bus work (torque on/off, clearing faults) is queued with `call()` and runs between cycles.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from types import TracebackType
from typing import TypeVar

from servoface.hardware.driver import Driver
from servoface.hardware.errors import HardwareError
from servoface.hardware.snapshot import ChainSnapshot

T = TypeVar("T")


class DriverThread:
    """Runs ``driver.cycle(latest goals)`` every ``1 / rate_hz`` s on its own thread."""

    def __init__(self, driver: Driver, rate_hz: float = 100.0, *, name: str = "servoface-bus") -> None:
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        driver.hand_over()
        self.driver = driver
        self.period_s = 1.0 / rate_hz
        self._lock = threading.Lock()
        self._goals: dict[int, int] = {}
        self._snapshot: ChainSnapshot | None = None
        self._calls: list[tuple[Callable[[Driver], object], Future[object]]] = []
        self._stop = threading.Event()
        self._new_snapshot = threading.Condition(self._lock)
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> DriverThread:
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def __enter__(self) -> DriverThread:
        return self.start()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def submit_goals(self, goals_tick: Mapping[int, int]) -> None:
        """Goals for the next cycle (replacing any not yet sent). Raises `GoalRejectedError` here, at once."""
        checked = self.driver.validate_goals(goals_tick)
        self._raise_if_dead()
        with self._lock:
            self._goals = checked

    def snapshot(self) -> ChainSnapshot | None:
        with self._lock:
            return self._snapshot

    def wait_snapshot(self, after_cycle: int = -1, timeout_s: float = 2.0) -> ChainSnapshot:
        """Block until a snapshot newer than ``after_cycle`` exists."""
        deadline = time.monotonic() + timeout_s
        with self._new_snapshot:
            while self._snapshot is None or self._snapshot.cycle <= after_cycle:
                self._raise_if_dead()
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"no driver snapshot after cycle {after_cycle} within {timeout_s} s")
                self._new_snapshot.wait(min(left, 0.05))
            return self._snapshot

    def call(self, fn: Callable[[Driver], T], timeout_s: float = 5.0) -> T:
        """Run ``fn(driver)`` on the bus thread between cycles and return its result (or raise its error)."""
        future: Future[object] = Future()
        self._raise_if_dead()
        with self._lock:
            self._calls.append((fn, future))
        return future.result(timeout_s)  # type: ignore[return-value]

    def torque_on(self) -> None:
        self.call(lambda d: d.torque_on())

    def torque_off(self) -> tuple[int, ...]:
        """Torque off on every servo (retried, carrying on); the ids that did not confirm it."""
        return self.call(lambda d: d.torque_off(), timeout_s=30.0)

    def _raise_if_dead(self) -> None:
        if self.error is not None:
            raise HardwareError(f"driver thread stopped: {self.error!r}") from self.error

    def _run(self) -> None:
        next_t = time.monotonic()
        try:
            while not self._stop.is_set():
                with self._lock:
                    calls, self._calls = self._calls, []
                    goals, self._goals = self._goals, {}
                for fn, future in calls:
                    try:
                        future.set_result(fn(self.driver))
                    except BaseException as err:  # handed to the caller
                        future.set_exception(err)
                snap = self.driver.cycle(goals)
                with self._new_snapshot:
                    self._snapshot = snap
                    self._new_snapshot.notify_all()
                next_t += self.period_s
                delay = next_t - time.monotonic()
                if delay > 0:
                    self._stop.wait(delay)
                else:
                    next_t = time.monotonic()  # overran: do not try to catch up
        except BaseException as err:
            self.error = err
            with self._lock:
                for _, future in self._calls:
                    future.set_exception(err)
                self._calls = []
        finally:
            self.driver.hand_over()
