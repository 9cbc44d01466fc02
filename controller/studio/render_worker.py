"""The twin's renderer in a process of its own, so drawing and encoding never compete with the control
loop (and the web server) for the interpreter lock, and use the second core.

The child owns the EGL context, a twin of its own (``AchievableFace`` of the head and calibration it was
given) and the face model; the parent sends small requests over a pipe (the goals sent, AUs or actuator
targets) and gets PNG bytes back. The child exits when the pipe closes (the parent ended, however)."""

from __future__ import annotations

import multiprocessing
import queue
import signal
import sys
import threading
import types
from collections.abc import Mapping
from multiprocessing.connection import Connection
from typing import Any

from servoface.controller.studio.errors import StudioError

START_TIMEOUT_S = 120.0  # spawn + imports + EGL on a loaded 2-core machine
REPLY_TIMEOUT_S = 60.0


class RenderWorkerError(StudioError):
    """The render process failed to start, died, or could not draw a request."""

    status = 503
    code = "render_unavailable"


def _pose_for(op: str, payload: Mapping[Any, Any], model: Any, twin: Any) -> Any:
    from servoface.sim.rig import HeadPose

    if op == "goals":  # the achievable face: what the gate let through, posed by the twin
        joint_deg, offsets, targets = twin.gate.twin_pose({int(k): int(v) for k, v in payload.items()})
        return HeadPose(joint_deg=joint_deg, skin_offset_mm=offsets, actuator_targets=targets)
    if op == "target":  # the muscle model's wish
        return model.solve(dict(payload))
    if op == "still":  # the servos' best still of these AUs
        return twin.still(dict(payload)).pose
    if op == "targets":  # actuators at targets (role -> deg / mm), the rest at neutral
        return model.pose_from_targets(dict(payload))
    raise ValueError(f"unknown render request {op!r}")


def worker_main(conn: Connection, head: Any, calibration: Any, period_s: float, width: int, height: int) -> None:
    """The child's body (module level: the spawn start method imports it). Stop signals are the parent's to
    handle (a terminal's Ctrl-C reaches the whole process group): the child ends when the parent closes the
    pipe or sends None, after the head is safe, and never with a traceback of its own."""
    for stop_signal in (signal.SIGINT, signal.SIGHUP):
        signal.signal(stop_signal, signal.SIG_IGN)
    try:
        from servoface.controller.studio.framing import LiveRenderer
        from servoface.controller.studio.png import encode_png
        from servoface.sim.achievable import AchievableFace
        from servoface.sim.face_model import FaceModel

        model = FaceModel(head)
        twin = AchievableFace(head, calibration, frame_period_s=period_s, model=model)
        renderer = LiveRenderer(width, height)  # the whole head, crown included (see its module)
    except Exception as err:  # noqa: BLE001 - reported to the parent, which runs without renders
        conn.send(("error", f"{type(err).__name__}: {err}"))
        conn.close()
        return
    conn.send(("ready", ""))
    # drawing and encoding overlap: this thread draws request N+1 while the encoder thread compresses N
    # (glReadPixels, numpy and zlib all run without the GIL); replies leave in request order, one sender
    replies: queue.Queue[tuple[str, Any] | None] = queue.Queue(maxsize=2)

    def encoder() -> None:
        while (item := replies.get()) is not None:
            kind, value = item
            try:
                conn.send(("ok", encode_png(value)) if kind == "pixels" else (kind, value))
            except Exception as err:  # noqa: BLE001 - the pipe is gone: the parent ended
                if isinstance(err, (OSError, EOFError, BrokenPipeError)):
                    return
                conn.send(("error", f"{type(err).__name__}: {err}"))

    sender = threading.Thread(target=encoder, name="studio-render-png", daemon=True)
    sender.start()
    try:
        while True:
            try:
                request = conn.recv()
            except (EOFError, OSError):
                return
            if request is None:
                return
            op, payload = request
            try:
                if op == "calibration":  # the head's calibration changed: a new twin for it
                    twin = AchievableFace(head, payload["calibration"], frame_period_s=period_s, model=model)
                    replies.put(("ok", b""))
                    continue
                replies.put(("pixels", renderer.render(head, _pose_for(op, payload, model, twin))))
            except Exception as err:  # noqa: BLE001 - one bad request must not end the twin
                replies.put(("error", f"{type(err).__name__}: {err}"))
    finally:
        replies.put(None)
        sender.join(10.0)
        renderer.close()
        conn.close()


def _start_without_main(process: Any) -> None:
    """Start ``process`` without the child re-running the parent's ``__main__``: the spawn start method
    would import the main script again, and a user's script without an ``if __name__ == "__main__"``
    guard would open a second head in the child. The child needs nothing from it (its target and
    arguments are servoface's), so for the moment of the start the main module is an empty one."""
    main = sys.modules.get("__main__")
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        process.start()
    finally:
        if main is not None:
            sys.modules["__main__"] = main


class RenderWorker:
    """The parent's handle: ``png(op, payload)`` from one thread at a time (the studio's render thread)."""

    def __init__(self, head: Any, calibration: Any, period_s: float, width: int, height: int) -> None:
        ctx = multiprocessing.get_context("spawn")  # never fork a process that has threads and GL
        self._conn, child = ctx.Pipe(duplex=True)
        self._process = ctx.Process(
            target=worker_main,
            args=(child, head, calibration, period_s, width, height),
            name="studio-render",
            daemon=True,
        )
        _start_without_main(self._process)
        child.close()
        kind, text = self._reply(START_TIMEOUT_S)
        if kind != "ready":
            self.close()
            raise RenderWorkerError(text)

    def _reply(self, timeout_s: float) -> tuple[str, Any]:
        try:
            if not self._conn.poll(timeout_s):
                raise RenderWorkerError(f"the render process did not answer within {timeout_s:g} s")
            reply: tuple[str, Any] = self._conn.recv()
        except (EOFError, OSError) as err:
            raise RenderWorkerError(f"the render process ended (exit code {self._process.exitcode})") from err
        return reply

    def submit(self, op: str, payload: Mapping[Any, Any]) -> None:
        """Send one request; its PNG comes back from ``result()`` (replies arrive in request order)."""
        try:
            self._conn.send((op, dict(payload)))
        except (OSError, ValueError) as err:
            raise RenderWorkerError(f"the render process is gone: {err}") from err

    def result(self) -> bytes:
        """The PNG of the oldest request not yet collected (RenderWorkerError if it failed)."""
        kind, value = self._reply(REPLY_TIMEOUT_S)
        if kind != "ok":
            raise RenderWorkerError(f"render failed: {value}")
        return bytes(value)

    def png(self, op: str, payload: Mapping[Any, Any]) -> bytes:
        """One PNG now (no other request may be outstanding)."""
        self.submit(op, payload)
        return self.result()

    @property
    def alive(self) -> bool:
        return self._process.is_alive()

    def close(self) -> None:
        try:
            self._conn.send(None)
        except (OSError, ValueError):
            pass
        self._process.join(10.0)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(5.0)
        self._conn.close()
