"""The tracks' live state on the loop thread: what each plays now, what is scheduled, and the mix.

Only the loop thread touches a :class:`TrackTable`; other threads see the immutable :class:`TrackView`
it publishes after every frame.
"""

from __future__ import annotations

import bisect
import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from servoface.controller.errors import ControllerError
from servoface.controller.service.handles import CommandHandle, Status
from servoface.controller.service.sources import Source
from servoface.controller.service.tracks import Mixer

#: ``activate(slot, t0_s)`` puts a command's source on its track (loop thread, at its start time).
Activate = Callable[["Slot", float], None]
Notify = Callable[[CommandHandle], None]


@dataclass(frozen=True)
class TrackView:
    """One track as other threads see it (after the last frame)."""

    name: str
    source: str | None  # what plays (None: the track is empty)
    command_id: int | None
    state: str  # "empty", "running", "holding"
    scheduled: int  # commands waiting for their start time
    aus: Mapping[str, float]


@dataclass(order=True)
class _Pending:
    at_s: float
    seq: int
    handle: CommandHandle = field(compare=False)
    activate: Activate = field(compare=False)


class Slot:
    """One track: its current source and handle, its last output, and the scheduled commands."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.source: Source | None = None
        self.handle: CommandHandle | None = None
        self.last: dict[str, float] = {}
        self.pending: list[_Pending] = []

    def install(self, source: Source, handle: CommandHandle, t0_s: float, notify: Notify) -> None:
        """Put ``source`` on the track from ``t0_s``, starting from the track's last output."""
        self.replace(handle, t0_s, notify, f"taken over by #{handle.id}")
        current = self.source
        if current is not None and not current.uses_below:  # where the track is now (two commands may
            try:  # start on one frame: the second starts from the first)
                self.last = dict(current.sample(t0_s, {}))
            except ControllerError:
                pass
        source.begin(t0_s, dict(self.last))
        self.source = source

    def targets(self, t_s: float) -> dict[str, float]:
        """Where the track is heading: its clip's end pose, or (other sources) where it is now."""
        source = self.source
        end = getattr(source, "target_pose", None)
        if end is not None:
            return dict(end())
        if source is not None and not source.uses_below:
            try:
                return dict(source.sample(t_s, {}))
            except ControllerError:
                pass
        return dict(self.last)

    def replace(self, handle: CommandHandle, t_s: float, notify: Notify, why: str) -> None:
        """Make ``handle`` the track's command; the previous one (if still going) is cancelled."""
        old = self.handle
        if old is not None and old is not handle and old._set(Status.CANCELLED, t_s, why):
            notify(old)
        self.handle = handle

    def clear(self, t_s: float, why: str, notify: Notify) -> None:
        """Empty the track now: cancel its command and everything scheduled on it."""
        for p in self.pending:
            if p.handle._set(Status.CANCELLED, t_s, why):
                notify(p.handle)
        self.pending.clear()
        if self.handle is not None and self.handle._set(Status.CANCELLED, t_s, why):
            notify(self.handle)
        self.source, self.handle, self.last = None, None, {}


class TrackTable:
    """All tracks in layer order, mixed by ``mixer``."""

    def __init__(self, mixer: Mixer) -> None:
        self.mixer = mixer
        self.slots: dict[str, Slot] = {t.name: Slot(t.name) for t in mixer.tracks}
        self._seq = itertools.count()

    def schedule(self, track: str, at_s: float, handle: CommandHandle, activate: Activate) -> None:
        bisect.insort(self.slots[track].pending, _Pending(at_s, next(self._seq), handle, activate))

    def clear_all(self, t_s: float, why: str, notify: Notify) -> None:
        for slot in self.slots.values():
            slot.clear(t_s, why, notify)

    def activate_due(self, t_s: float, notify: Notify) -> None:
        for slot in self.slots.values():
            while slot.pending and slot.pending[0].at_s <= t_s + 1e-9:
                p = slot.pending.pop(0)
                if p.handle.status.final:  # cancelled while waiting
                    continue
                try:
                    p.activate(slot, p.at_s)
                except ControllerError as err:
                    if p.handle._set(Status.FAILED, t_s, str(err), err):
                        notify(p.handle)
                    continue
                if p.handle._set(Status.RUNNING, p.at_s):
                    notify(p.handle)

    def sample(self, t_s: float, notify: Notify) -> dict[str, float]:
        """Every track's output at ``t_s`` mixed into one pose (a failing source fails its command and
        leaves its track empty; the others play on)."""
        contributions: list[tuple[str, Mapping[str, float]]] = []
        below: dict[str, float] = {}
        fresh = True
        mix = self.mixer.mix
        for slot in self.slots.values():
            source = slot.source
            if source is None:
                continue
            if source.uses_below and not fresh:
                below, fresh = mix(contributions), True
            try:
                aus = source.sample(t_s, below)
            except ControllerError as err:
                if slot.handle is not None and slot.handle._set(Status.FAILED, t_s, str(err), err):
                    notify(slot.handle)
                slot.source, slot.handle, slot.last = None, None, {}
                continue
            slot.last = dict(aus)
            if aus:
                contributions.append((slot.name, aus))
                fresh = False
        return mix(contributions)

    def fail_refused(
        self,
        t_s: float,
        err: Exception,
        notify: Notify,
        solves: Callable[[Mapping[str, float]], object],
        refused: tuple[type[Exception], ...],
    ) -> list[str]:
        """After a frame's mixed pose was refused on the head (``err``: its face model or the frame check
        refused it, so nothing of it was sent): the tracks whose own output the head refuses (``solves``
        raises one of ``refused`` on it) fail with that error; if none does alone (the mix is what the head
        refuses), every track that contributed does, with ``err``. A failed track is left empty, so the next
        frame mixes what is left instead of failing again with every waiter left waiting; its command's detail
        names the track and the source. A live source (a stream followed, an alive layer: ``live``) is not
        failed: it produces anew every frame, so only this frame is skipped (a stream message out of the head's
        range drops that message, not the stream). Returns the names of the tracks failed."""
        contributing = [s for s in self.slots.values() if s.source is not None and s.last]
        culprits: list[tuple[Slot, Exception]] = []
        for slot in contributing:
            try:
                solves(slot.last)
            except refused as own:
                culprits.append((slot, own))
        if not culprits:
            culprits = [(slot, err) for slot in contributing]
        failed: list[str] = []
        for slot, why in culprits:
            source = slot.source
            if getattr(source, "live", False):
                continue
            detail = f"track {slot.name!r} ({getattr(source, 'name', type(source).__name__)}): {why}"
            if slot.handle is not None and slot.handle._set(Status.FAILED, t_s, detail, why):
                notify(slot.handle)
            slot.source, slot.handle, slot.last = None, None, {}
            failed.append(slot.name)
        return failed

    def advance(self, t_s: float) -> list[CommandHandle]:
        """After the frame went out: running sources that finished leave their track (a holding one stays
        on it, an ended one leaves it empty); returns their commands, for the caller to complete once the
        frame is published (a waiter woken by DONE then sees that frame's status and trace)."""
        done: list[CommandHandle] = []
        for slot in self.slots.values():
            source = slot.source
            if source is None:
                continue
            state = source.state(t_s)
            if state == "running":
                continue
            if slot.handle is not None and not slot.handle.status.final:
                done.append(slot.handle)
            if state == "ended":
                slot.source, slot.handle, slot.last = None, None, {}
        return done

    def busy(self, t_s: float, alive: frozenset[str]) -> bool:
        """True while a non-alive track has a running source or a command scheduled."""
        for slot in self.slots.values():
            if slot.name in alive:
                continue
            if slot.pending or (slot.source is not None and slot.source.state(t_s) == "running"):
                return True
        return False

    def view(self, t_s: float) -> dict[str, TrackView]:
        out: dict[str, TrackView] = {}
        for name, slot in self.slots.items():
            src = slot.source
            state = "empty" if src is None else src.state(t_s)
            out[name] = TrackView(
                name,
                None if src is None else src.name,
                None if slot.handle is None else slot.handle.id,
                state,
                len(slot.pending),
                dict(slot.last),
            )
        return out
