"""Handles: what every command returns. Poll ``status`` or ``wait()`` for it from any thread.

Life of a command: ``pending`` (accepted, waiting for its start time or the next frame) -> ``running``
(its source is on its track; or, for an instant command, being applied) -> one of ``done`` (its motion
finished; a held pose stays on the track), ``cancelled`` (stopped, taken over by a newer command on the
same track, or swept away by an e-stop / torque-off / shutdown) or ``failed`` (``error`` says why).
"""

from __future__ import annotations

import itertools
import threading
from dataclasses import dataclass
from enum import StrEnum

from servoface.controller.service.errors import CommandFailedError, ServiceError


class Status(StrEnum):
    PENDING = "pending"
    RUNNING = "running"
    DONE = "done"
    CANCELLED = "cancelled"
    FAILED = "failed"

    @property
    def final(self) -> bool:
        return self in (Status.DONE, Status.CANCELLED, Status.FAILED)


_ids = itertools.count(1)


@dataclass(frozen=True)
class PlaybackEvent:
    """A status change of a command, as the ``playback`` observers see it."""

    t_s: float  # service time
    command_id: int
    kind: str
    track: str | None
    status: Status
    detail: str = ""


class CommandHandle:
    """The submitted command's status (thread-safe). ``started_s`` / ``finished_s`` are service times."""

    def __init__(self, kind: str, track: str | None = None, at_s: float | None = None) -> None:
        self.id = next(_ids)
        self.kind = kind
        self.track = track
        self.at_s = at_s
        self.started_s: float | None = None
        self.finished_s: float | None = None
        self.detail = ""
        self.error: BaseException | None = None
        self._status = Status.PENDING
        self._cond = threading.Condition()

    def __repr__(self) -> str:
        where = f" on {self.track}" if self.track else ""
        return f"<CommandHandle #{self.id} {self.kind}{where}: {self._status}>"

    @property
    def status(self) -> Status:
        return self._status

    def done(self) -> bool:
        """True once the command is final (done, cancelled or failed)."""
        return self._status.final

    def wait(self, timeout_s: float | None = None) -> Status:
        """Block until final or ``timeout_s`` passes; returns the status then (waits in slices, so a
        Ctrl-C in the main thread is delivered promptly)."""
        deadline = None if timeout_s is None else max(0.0, float(timeout_s))
        waited = 0.0
        with self._cond:
            while not self._status.final:
                if deadline is not None and waited >= deadline:
                    break
                step = 0.05 if deadline is None else min(0.05, deadline - waited)
                self._cond.wait(step)
                waited += step
            return self._status

    def result(self, timeout_s: float | None = None) -> Status:
        """Like ``wait`` but raise the command's error if it failed (CommandFailedError if it had none), and
        ServiceError if it is still not final after ``timeout_s``."""
        status = self.wait(timeout_s)
        if status is Status.FAILED:
            if self.error is not None:
                raise self.error
            raise CommandFailedError(f"command #{self.id} {self.kind} failed: {self.detail}")
        if not status.final:
            raise ServiceError(f"command #{self.id} {self.kind} still {status} after {timeout_s} s")
        return status

    # -- set by the service (loop thread) ------------------------------------------------------------
    def _set(self, status: Status, t_s: float, detail: str = "", error: BaseException | None = None) -> bool:
        """Move to ``status``; False (and no change) if already final."""
        with self._cond:
            if self._status.final:
                return False
            self._status = status
            if status is Status.RUNNING:
                self.started_s = t_s
            if status.final:
                self.finished_s = t_s
            if detail:
                self.detail = detail
            if error is not None:
                self.error = error
            self._cond.notify_all()
            return True

    def _event(self) -> PlaybackEvent:
        t = self.finished_s if self._status.final else self.started_s
        return PlaybackEvent(t if t is not None else 0.0, self.id, self.kind, self.track, self._status, self.detail)
