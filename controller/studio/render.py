"""The live twin for the studio: one render thread drives a render process of its own
(:mod:`servoface.controller.studio.render_worker`: it owns the EGL context and a twin) that draws the
achievable face (the goals the gate let through) and, on demand, the muscle model's target, at 640x480,
encodes PNGs (:mod:`servoface.controller.studio.png`) and hands them to the studio; drawing never holds
this process's interpreter lock, so it does not compete with the control loop. It renders only when the
pose changed and someone is watching, newest first: a slow browser skips frames, it never makes the loop
wait. Previews (a script at a time, the calibration pose) go through the same thread."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

from servoface.controller.pipeline import FrameTrace
from servoface.controller.service import HeadService
from servoface.controller.studio.png import encode_png
from servoface.controller.studio.render_worker import RenderWorker, RenderWorkerError

WIDTH, HEIGHT = 640, 480
MAX_FPS = 30.0


@dataclass(frozen=True)
class TwinImage:
    """One encoded render: ``which`` achievable | target, ``seq`` counts renders, ``frame_index`` the
    pipeline frame it shows."""

    which: str
    seq: int
    frame_index: int
    verdict: str
    png: bytes
    t_s: float


__all__ = ["HEIGHT", "WIDTH", "TwinImage", "TwinRenderer", "encode_png"]


class TwinRenderer:
    """See the module docstring. ``on_image(TwinImage)`` is called on the render thread."""

    def __init__(
        self,
        service: HeadService,
        *,
        width: int = WIDTH,
        height: int = HEIGHT,
        max_fps: float = MAX_FPS,
        on_image: Callable[[TwinImage], None] | None = None,
    ) -> None:
        self.service = service
        self.head = service.head
        self.width, self.height = width, height
        self.min_period_s = 1.0 / max_fps
        self.on_image = on_image
        self.watch_achievable = 0  # how many clients want live images (the studio keeps these counts)
        self.watch_target = 0
        self.latest: dict[str, TwinImage] = {}
        self.renders = 0
        self.error = ""
        self._requests: queue.Queue[tuple[Callable[[Any], Any], Future[Any]] | None] = queue.Queue()
        self._stop = threading.Event()
        self._ready = threading.Event()
        self._seq = 0
        self._lock = threading.Lock()
        self._worker: RenderWorker | None = None
        self._pending: tuple[FrameTrace, str] | None = None  # the live render asked for, not yet collected
        self._thread = threading.Thread(target=self._run, name="studio-twin", daemon=True)
        self._thread.start()

    # -- from any thread ---------------------------------------------------------------------------
    def wait_ready(self, timeout_s: float = 60.0) -> bool:
        return self._ready.wait(timeout_s)

    def call(self, fn: Callable[[Any], Any], timeout_s: float = 30.0) -> Any:
        """Run ``fn(self_on_thread)`` on the render thread (it owns the GL context) and return its result."""
        fut: Future[Any] = Future()
        self._requests.put((fn, fut))
        return fut.result(timeout_s)

    def render_aus_png(self, aus: Mapping[str, float], which: str = "achievable") -> bytes:
        """One PNG of ``aus`` as the servos would make it (``achievable``: the twin's still) or as the muscle
        model wishes (``target``); nothing moves."""

        op = "target" if which == "target" else "still"
        return bytes(self.call(lambda me: me._png(op, dict(aus))))

    def render_targets_png(self, targets: Mapping[str, float]) -> bytes:
        """One PNG of the head with actuators at ``targets`` (role -> deg / mm), the rest at neutral."""

        return bytes(self.call(lambda me: me._png("targets", dict(targets))))

    def set_calibration(self, calibration: Any) -> None:
        """The running head's calibration changed: the render process rebuilds its twin with it (the
        achievable face is posed from the goals through the calibration's inverse)."""
        self.latest.clear()
        if self._worker is None or self.error:
            return
        try:
            self.call(lambda me: me._png("calibration", {"calibration": calibration}), timeout_s=120.0)
        except Exception as err:  # noqa: BLE001 - the twin goes on with the old one; say so
            self.error = f"the twin could not take the new calibration: {err}"

    def latest_png(self, which: str) -> TwinImage | None:
        """The newest image of ``which``; rendered now when there is none yet."""
        known = self.latest.get(which)
        if known is not None:
            return known
        trace = self.service.last_trace
        if trace is None:
            return None
        return self.call(lambda me: me._render(trace, which))  # type: ignore[no-any-return]

    def close(self) -> None:
        self._stop.set()
        self._requests.put(None)
        self._thread.join(10.0)

    # -- the render thread -------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            self._worker = RenderWorker(
                self.head, self.service.pipeline.calibration, self.service.period_s, self.width, self.height
            )
        except Exception as err:  # noqa: BLE001 - no renders (no EGL); the rest of the studio works
            self.error = f"{type(err).__name__}: {err}"
            self._ready.set()
            self._serve_failures()
            return
        self._ready.set()
        shown: dict[str, tuple[Any, ...]] = {}
        last_s = 0.0
        try:
            while not self._stop.is_set():
                self._serve_requests(block_s=0.0)
                wanted = [w for w, n in (("achievable", self.watch_achievable), ("target", self.watch_target)) if n > 0]
                trace = self.service.last_trace
                wait_s = self.min_period_s - (time.monotonic() - last_s)
                if not wanted or trace is None or wait_s > 0:
                    self._serve_requests(block_s=max(wait_s, 0.02) if wanted else 0.1)
                    continue
                did = False
                for which in wanted:
                    key = _key(trace, which)
                    if shown.get(which) == key:  # the pose did not change: nothing new to draw
                        continue
                    shown[which] = key
                    self._render_live(trace, which)
                    did = True
                if did:
                    last_s = time.monotonic()
                else:
                    self._collect_live()  # the pose rests: show its image now
                    self._serve_requests(block_s=0.01)
        except RenderWorkerError:
            self._worker.close()
            self._serve_failures()
        finally:
            self._worker.close()

    def _png(self, op: str, payload: Mapping[Any, Any]) -> bytes:
        if self._worker is None:
            raise RenderWorkerError("the render process has not started")
        self._collect_live()
        return self._worker.png(op, payload)

    def _render_live(self, trace: FrameTrace, which: str) -> None:
        """Ask for ``trace``'s image, then collect the one asked for before it: the render process draws
        this one while it encodes that one. At most one live request is outstanding."""
        assert self._worker is not None
        if which == "target":
            self._worker.submit("target", trace.aus)
        else:
            self._worker.submit("goals", trace.goals_sent)
        before, self._pending = self._pending, (trace, which)
        if before is not None:
            self._publish_result(*before)

    def _collect_live(self) -> None:
        before, self._pending = self._pending, None
        if before is not None:
            self._publish_result(*before)

    def _publish_result(self, trace: FrameTrace, which: str) -> None:
        assert self._worker is not None
        try:
            self._publish(trace, which, self._worker.result())
        except RenderWorkerError as err:
            self.error = str(err)
            if not self._worker.alive:
                raise

    def _render(self, trace: FrameTrace, which: str) -> TwinImage:
        """Render and encode ``trace`` now (on the render thread, in the render process)."""
        if which == "target":
            png = self._png("target", trace.aus)
        else:
            png = self._png("goals", trace.goals_sent)
        return self._publish(trace, which, png)

    def _publish(self, trace: FrameTrace, which: str, png: bytes) -> TwinImage:
        with self._lock:
            self._seq += 1
            seq = self._seq
            self.renders += 1
        image = TwinImage(which, seq, trace.index, trace.verdict, png, trace.t_s)
        self.latest[which] = image
        if self.on_image is not None:
            try:
                self.on_image(image)
            except Exception:  # noqa: BLE001 - a failing listener must not stop the twin
                pass
        return image

    def _serve_requests(self, block_s: float) -> None:
        try:
            item = self._requests.get(timeout=block_s) if block_s > 0 else self._requests.get_nowait()
        except queue.Empty:
            return
        while item is not None:
            fn, fut = item
            if fut.set_running_or_notify_cancel():
                try:
                    fut.set_result(fn(self))
                except BaseException as err:  # noqa: BLE001 - handed to the caller
                    fut.set_exception(err)
            try:
                item = self._requests.get_nowait()
            except queue.Empty:
                return

    def _serve_failures(self) -> None:
        while not self._stop.is_set():
            item = self._requests.get()
            if item is None:
                continue
            item[1].set_exception(RenderWorkerError(f"the twin cannot render here: {self.error}"))


def _key(trace: FrameTrace, which: str) -> tuple[Any, ...]:
    """What a render of ``which`` depends on: the goals sent (achievable) or the AUs (target)."""
    if which == "target":
        return tuple((au, round(v, 4)) for au, v in sorted(trace.aus.items()) if abs(v) > 1e-6)
    return tuple(sorted(trace.goals_sent.items()))
