"""Borrowing the bus from the head service for work the loop cannot do: manual jogs, one servo's torque,
a reboot, a calibration session.

One thread of the studio's own (the *lender*) pauses the service loop (``HeadService.pause``: the loop
stops at a frame boundary and hands the driver over), owns the driver while it works, and resumes the
loop from the same thread (the service re-pins its goals to what the driver last put on the wire, so
nothing jumps). In **manual** mode it keeps the bus between jobs and reads telemetry at ``poll_hz``
(which also keeps the Bus Watchdog fed). An e-stop is answered on this thread at once (torque off on every
servo), ends manual mode and aborts a calibration; the service applies its own e-stop on resume."""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from servoface.controller.service import HeadService
from servoface.controller.studio.errors import ConflictError, StudioError
from servoface.hardware.driver import Driver
from servoface.hardware.errors import HardwareError
from servoface.hardware.snapshot import ChainSnapshot

Job = Callable[[Driver], Any]


@dataclass
class _Pending:
    job: Job
    done: threading.Event = field(default_factory=threading.Event)
    result: Any = None
    error: BaseException | None = None


class BusLender:
    """See the module docstring. ``on_snapshot`` is called (on the lender thread) with each telemetry
    snapshot read while the bus is lent; ``on_change`` when manual mode starts or ends."""

    def __init__(
        self,
        service: HeadService,
        *,
        poll_hz: float = 20.0,
        on_snapshot: Callable[[ChainSnapshot], None] | None = None,
        on_change: Callable[[], None] | None = None,
    ) -> None:
        self.service = service
        self.poll_s = 1.0 / poll_hz
        self.on_snapshot = on_snapshot
        self.on_change = on_change
        self._jobs: queue.Queue[_Pending | None] = queue.Queue()
        self._manual = False
        self._want_manual = False
        self._busy = False  # a long job (a calibration) holds the bus
        self._estop = threading.Event()
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="studio-bus-lender", daemon=True)
        self._thread.start()

    # -- from any thread ---------------------------------------------------------------------------
    @property
    def manual(self) -> bool:
        return self._manual or self._want_manual

    @property
    def holding(self) -> bool:
        """True while the bus is lent (manual mode, a job or a calibration running)."""
        return self._manual or self._busy

    def set_manual(self, on: bool, timeout_s: float = 10.0) -> None:
        """Enter (the loop pauses) or leave (the loop resumes) manual mode; returns when it is so."""
        if on and self.service.estop_latched:
            raise ConflictError("manual mode: the e-stop is latched; clear it first")
        self._want_manual = bool(on)
        self.run(lambda driver: None, timeout_s=timeout_s)

    def run(self, job: Job, *, timeout_s: float = 10.0) -> Any:
        """Run ``job(driver)`` on the lender thread with the bus borrowed; its result, or its error."""
        if self._stop:
            raise ConflictError("the studio is shutting down")
        if self.service.driver is None:
            raise ConflictError("this head has no bus (offline)")
        pending = _Pending(job)
        self._jobs.put(pending)
        if not pending.done.wait(timeout_s):
            raise StudioError(f"the bus did not become free within {timeout_s:g} s", status=409, code="conflict")
        if pending.error is not None:
            raise pending.error
        return pending.result

    def estop(self) -> None:
        """Torque off on every servo now if the bus is lent; ends manual mode (call after service.estop)."""
        self._want_manual = False
        self._estop.set()
        self._jobs.put(None)  # wake the thread

    @property
    def estop_pending(self) -> bool:
        return self._estop.is_set()

    def close(self) -> None:
        self._stop = True
        self._want_manual = False
        self._jobs.put(None)
        self._thread.join(10.0)

    # -- the lender thread -------------------------------------------------------------------------
    def _run(self) -> None:
        while True:
            try:
                item = self._jobs.get(timeout=self.poll_s if self._manual else None)
            except queue.Empty:
                item = None
                self._poll()
            if self._estop.is_set():
                self._torque_off_now()
            if item is not None:
                self._do(item)
            if self._manual and not self._want_manual:
                self._give_back()
            if self._stop:
                if self._manual:
                    self._give_back()
                self._fail_rest()
                return

    def _borrow(self) -> Driver:
        driver = self.service.driver
        if driver is None:
            raise ConflictError("this head has no bus (offline)")
        if not self._manual:
            self.service.pause()
        return driver

    def _do(self, item: _Pending) -> None:
        borrowed = False
        try:
            driver = self._borrow()
            borrowed = True
            self._busy = True
            item.result = item.job(driver)
        except BaseException as err:  # handed to the caller's thread
            item.error = err
        finally:
            self._busy = False
            if borrowed:
                if self._want_manual and not self._estop.is_set():
                    if not self._manual:
                        self._manual = True
                        self._changed()
                    self._poll()
                elif self._manual:
                    self._give_back()
                else:
                    self._resume()
            item.done.set()

    def _poll(self) -> None:
        driver = self.service.driver
        if not self._manual or driver is None:
            return
        try:
            snap = driver.read_state()
        except HardwareError:
            return
        self.service.pipeline.last_snapshot = snap
        if self.on_snapshot is not None:
            self.on_snapshot(snap)

    def _torque_off_now(self) -> None:
        self._estop.clear()
        if self._manual:
            driver = self.service.driver
            if driver is not None:
                try:
                    driver.torque_off()
                except HardwareError:
                    pass
            self._give_back()

    def _give_back(self) -> None:
        self._manual = False
        self._resume()
        self._changed()

    def _resume(self) -> None:
        try:
            self.service.resume()
        except StudioError:
            pass

    def _changed(self) -> None:
        if self.on_change is not None:
            try:
                self.on_change()
            except Exception:  # noqa: BLE001 - an observer's failure must not stop the lender
                pass

    def _fail_rest(self) -> None:
        while True:
            try:
                item = self._jobs.get_nowait()
            except queue.Empty:
                return
            if item is not None:
                item.error = ConflictError("the studio is shutting down")
                item.done.set()
