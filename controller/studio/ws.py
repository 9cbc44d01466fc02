"""One browser's WebSocket (see API.md "WebSocket"): pushes the studio's messages and twin renders,
and takes slider moves, expressions, gaze, e-stop and hold. Outgoing JSON goes through a bounded queue
(full: the oldest frame/telemetry is dropped), a twin render through a one-slot mailbox (newest wins), so
a slow tab falls behind gracefully and never holds anything up. Messages in are handled in order, each
validated like its HTTP twin; a bad one gets an ``error`` message and the socket stays open."""

from __future__ import annotations

import asyncio
import json
import struct
from typing import Any

from servoface.controller.script_fields import shown
from servoface.controller.studio import models as m
from servoface.controller.studio.errors import BadJsonError, InvalidValueError, StudioError, TooLargeError
from servoface.controller.studio.render import TwinImage
from servoface.controller.studio.security import MAX_WS_MESSAGE_BYTES, RateLimiter
from servoface.controller.studio.studio import Studio

QUEUE_MAX = 64
DROPPABLE = frozenset({"frame", "telemetry", "state"})
KIND_BYTE = {"achievable": 0x41, "target": 0x54}


class _Client:
    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self.queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue()
        self.image: dict[str, TwinImage] = {}
        self.wake = asyncio.Event()
        self.twin = True
        self.target = False
        self.telemetry = True
        self.frames = True
        self.key = 0  # the studio's liveness key of this socket

    # called from other threads
    def offer(self, message: dict[str, Any]) -> None:
        kind = message.get("type")
        if (kind == "telemetry" and not self.telemetry) or (kind == "frame" and not self.frames):
            return
        self.loop.call_soon_threadsafe(self._put, message)

    def offer_image(self, image: TwinImage) -> None:
        if (image.which == "achievable" and self.twin) or (image.which == "target" and self.target):
            self.loop.call_soon_threadsafe(self._put_image, image)

    # on the event loop
    def _put(self, message: dict[str, Any]) -> None:
        if self.queue.qsize() >= QUEUE_MAX:
            if message.get("type") in DROPPABLE:
                return
            try:
                self.queue.get_nowait()  # the oldest goes; an event is never dropped for a frame
            except asyncio.QueueEmpty:
                pass
        self.queue.put_nowait(message)
        self.wake.set()

    def _put_image(self, image: TwinImage) -> None:
        self.image[image.which] = image
        self.wake.set()


MAX_ID_CHARS = 128
MAX_ID_INT = 2**53  # beyond it a JavaScript number no longer holds the integer exactly


def _id_problem(msg_id: Any) -> str | None:
    """Why a message's ``id`` cannot be echoed back (None: it can): a string of at most ``MAX_ID_CHARS``
    characters or an integer within ±2^53 is kept as given; anything else is refused, not echoed."""
    if msg_id is None:
        return None
    expected = f"expected a string of at most {MAX_ID_CHARS} characters or an integer within ±2^53"
    if isinstance(msg_id, str):
        return None if len(msg_id) <= MAX_ID_CHARS else f"id: {expected}, got a string of {len(msg_id)} characters"
    if isinstance(msg_id, int) and not isinstance(msg_id, bool):
        if -MAX_ID_INT <= msg_id <= MAX_ID_INT:
            return None
        return f"id: {expected}, got an integer of {len(str(abs(msg_id)))} digits"
    return f"id: {expected}, got {type(msg_id).__name__} {shown(msg_id)}"


def _error_message(err: StudioError, msg_id: Any) -> dict[str, Any]:
    return {"type": "error", "id": msg_id, **err.body()}


async def serve_socket(studio: Studio, websocket: Any, limiter: RateLimiter | None = None) -> None:
    from starlette.concurrency import run_in_threadpool
    from starlette.websockets import WebSocketDisconnect

    await websocket.accept()
    client = _Client(asyncio.get_running_loop())
    studio.listeners.append(client.offer)
    studio.image_listeners.append(client.offer_image)
    _watch(studio, client, +1)
    key = client.key = studio.client_joined()
    who = str((websocket.client or ("?", 0))[0])
    sender = asyncio.create_task(_send_loop(websocket, client))
    try:
        await websocket.send_text(json.dumps({"type": "hello", "head": studio.head(), "state": studio.state()}))
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                break
            text = message.get("text")
            msg_id: Any = None
            studio.client_heard(key, busy=+1)  # anything that arrives counts as alive
            try:
                if text is None:
                    raise BadJsonError("expected a JSON text message (binary is not accepted)")
                if len(text) > MAX_WS_MESSAGE_BYTES:
                    raise TooLargeError(f"message over {MAX_WS_MESSAGE_BYTES} bytes", field="message")
                if limiter is not None:
                    limiter.take(who)
                try:
                    data = json.loads(text)
                except (ValueError, RecursionError) as err:
                    raise BadJsonError(f"message: not JSON ({err})") from None
                if not isinstance(data, dict):
                    raise BadJsonError("message: expected a JSON object with a 'type'")
                msg_id = data.pop("id", None)
                problem = _id_problem(msg_id)
                if problem is not None:
                    msg_id = None  # never echoed: the error reply carries "id": null
                    raise InvalidValueError(problem, field="id")
                result = await _dispatch(studio, client, data, run_in_threadpool)
                if msg_id is not None:
                    client._put({"type": "reply", "id": msg_id, "result": result})
            except StudioError as err:
                client._put(_error_message(err, msg_id))
            finally:
                studio.client_heard(key, busy=-1)
    except WebSocketDisconnect:
        pass
    finally:
        sender.cancel()
        studio.listeners.remove(client.offer)
        studio.image_listeners.remove(client.offer_image)
        _watch(studio, client, -1)
        await run_in_threadpool(studio.client_left, key)


def _watch(studio: Studio, client: _Client, sign: int) -> None:
    r = studio.renderer
    if r is None:
        return
    if client.twin:
        r.watch_achievable = max(0, r.watch_achievable + sign)
    if client.target:
        r.watch_target = max(0, r.watch_target + sign)


async def _dispatch(studio: Studio, client: _Client, data: dict[str, Any], run: Any) -> Any:
    kind = data.pop("type", None)
    if kind == "set_aus":
        return await run(studio.set_aus, m.parse(m.SetAus, data))
    if kind == "clear_aus":
        return await run(studio.clear_aus, m.parse(m.ClearAus, data))
    if kind == "express":
        return await run(studio.express, m.parse(m.Express, data))
    if kind == "gaze":
        return await run(studio.gaze, m.parse(m.Gaze, data))
    if kind == "estop":
        return await run(studio.estop, m.parse(m.EStop, data))
    if kind == "hold":
        return await run(studio.set_hold, m.parse(m.Hold, data))
    if kind == "subscribe":
        body = m.parse(m.Subscribe, data)
        _watch(studio, client, -1)
        for name in ("twin", "target", "telemetry", "frames"):
            value = getattr(body, name)
            if value is not None:
                setattr(client, name, value)
        _watch(studio, client, +1)
        return {n: getattr(client, n) for n in ("twin", "target", "telemetry", "frames")}
    if kind == "heartbeat":  # arms this socket's liveness watch (liveness.py)
        m.parse(m.Empty, data)
        studio.client_heard(client.key, heartbeat=True)
        return {"t_s": round(studio.service.now_s(), 4)}
    if kind == "ping":
        m.parse(m.Empty, data)
        return {"t_s": round(studio.service.now_s(), 4)}
    known = "set_aus, clear_aus, express, gaze, estop, hold, subscribe, heartbeat, ping"
    raise InvalidValueError(f"type: expected one of {known}, got {kind!r}", field="type")


async def _send_loop(websocket: Any, client: _Client) -> None:
    try:
        while True:
            await client.wake.wait()
            client.wake.clear()
            while not client.queue.empty():
                await websocket.send_text(json.dumps(client.queue.get_nowait()))
            for which in list(client.image):
                image = client.image.pop(which)
                await websocket.send_text(
                    json.dumps(
                        {"type": "twin", "seq": image.seq, "which": which, "frame_index": image.frame_index,
                         "verdict": image.verdict}
                    )
                )  # fmt: skip
                await websocket.send_bytes(bytes([KIND_BYTE[which]]) + struct.pack(">I", image.seq) + image.png)
    except asyncio.CancelledError:
        raise
    except Exception:  # noqa: BLE001 - the socket is gone; the receive side ends the session
        return
