"""The live twin for the studio: one render thread (it owns the EGL context) draws the achievable face
(the goals the gate let through, posed by a twin of its own) and, on demand, the muscle model's target,
at 640x480, encodes PNGs and hands them to the studio. It renders only when the frame changed and someone
is watching, newest first: a slow browser skips frames, it never makes the loop wait. Previews (a script
at a time, the calibration pose) go through the same thread."""

from __future__ import annotations

import io
import queue
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

from servoface.controller.pipeline import FrameTrace
from servoface.controller.service import HeadService

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


def encode_png(rgb: Any) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG", compress_level=1)
    return buf.getvalue()


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
        self._encoder = ThreadPoolExecutor(1, thread_name_prefix="studio-png")
        self._encode_lock = threading.Lock()
        self._encode_next: dict[str, tuple[FrameTrace, Any]] = {}
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

        def draw(me: TwinRenderer) -> bytes:
            if which == "target":
                return encode_png(me._renderer.render(me.head, me._model.solve(dict(aus))))
            return encode_png(me._renderer.render(me.head, me._twin.still(dict(aus)).pose))

        return bytes(self.call(draw))

    def render_targets_png(self, targets: Mapping[str, float]) -> bytes:
        """One PNG of the head with actuators at ``targets`` (role -> deg / mm), the rest at neutral."""

        def draw(me: TwinRenderer) -> bytes:
            return encode_png(me._renderer.render(me.head, me._model.pose_from_targets(dict(targets))))

        return bytes(self.call(draw))

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
            from servoface.sim.achievable import AchievableFace
            from servoface.sim.face_model import FaceModel
            from servoface.sim.render import HeadRenderer

            cal = self.service.pipeline.calibration
            self._model = FaceModel(self.head)
            self._twin = AchievableFace(self.head, cal, frame_period_s=self.service.period_s, model=self._model)
            self._renderer = HeadRenderer(self.width, self.height)
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
                    if shown.get(which) == key:
                        continue
                    shown[which] = key
                    self._render_live(trace, which)
                    did = True
                if did:
                    last_s = time.monotonic()
                else:
                    self._serve_requests(block_s=0.01)
        finally:
            self._encoder.shutdown(wait=True)
            self._renderer.close()

    def _pixels(self, trace: FrameTrace, which: str) -> Any:
        from servoface.sim.rig import HeadPose

        if which == "target":
            pose = self._model.solve(trace.aus)
        else:
            joint_deg, offsets, targets = self._twin.gate.twin_pose(trace.goals_sent)
            pose = HeadPose(joint_deg=joint_deg, skin_offset_mm=offsets, actuator_targets=targets)
        return self._renderer.render(self.head, pose)

    def _render(self, trace: FrameTrace, which: str) -> TwinImage:
        """Render and encode now (on the render thread): for one-off requests."""
        return self._publish(trace, which, self._pixels(trace, which))

    def _render_live(self, trace: FrameTrace, which: str) -> None:
        """Render here, encode on the encoder thread (zlib runs without the GIL): the next render overlaps
        this one's encoding. At most one encode waits per kind; a newer render replaces it."""
        rgb = self._pixels(trace, which)
        with self._encode_lock:
            waiting = which in self._encode_next
            self._encode_next[which] = (trace, rgb)
        if not waiting:
            self._encoder.submit(self._encode_one, which)

    def _encode_one(self, which: str) -> None:
        with self._encode_lock:
            item = self._encode_next.pop(which, None)
        if item is not None:
            self._publish(item[0], which, item[1])

    def _publish(self, trace: FrameTrace, which: str, rgb: Any) -> TwinImage:
        png = encode_png(rgb)
        with self._encode_lock:
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
            item[1].set_exception(RuntimeError(f"the twin cannot render here: {self.error}"))


def _key(trace: FrameTrace, which: str) -> tuple[Any, ...]:
    """What a render of ``which`` depends on: the goals sent (achievable) or the AUs (target)."""
    if which == "target":
        return tuple((au, round(v, 4)) for au, v in sorted(trace.aus.items()) if abs(v) > 1e-6)
    return tuple(sorted(trace.goals_sent.items()))
