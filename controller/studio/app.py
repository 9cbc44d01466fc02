"""The FastAPI app: the routes of API.md, each a thin call into :class:`Studio` with a validated body,
the static front end, and the gatekeeper around all of it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request, WebSocket
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, Response
from servoface.controller.studio import models as m
from servoface.controller.studio.errors import BadJsonError, InvalidValueError, NotFoundError, StudioError
from servoface.controller.studio.gate import Gatekeeper
from servoface.controller.studio.security import TOKEN_COOKIE, OriginPolicy, RateLimiter, token_matches
from servoface.controller.studio.studio import Studio
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException

STATIC_DIR = Path(__file__).resolve().parent / "static"
PLACEHOLDER = """<!doctype html><meta charset="utf-8"><title>servoface studio</title>
<p>The studio's front end is not installed (controller/studio/static/index.html); the API is at /api/.</p>"""


def create_app(studio: Studio, token: str, origins: OriginPolicy, limiter: RateLimiter | None = None) -> Any:
    """The ASGI app (FastAPI inside the gatekeeper)."""
    from servoface.controller.studio.ws import serve_socket

    api = FastAPI(title="servoface studio", docs_url=None, redoc_url=None, openapi_url=None, redirect_slashes=False)

    @api.exception_handler(StudioError)
    async def _studio_error(request: Request, err: StudioError) -> JSONResponse:
        headers = {"Retry-After": "1"} if err.status == 429 else None
        return JSONResponse(err.body(), status_code=err.status, headers=headers)

    @api.exception_handler(RequestValidationError)
    async def _path_error(request: Request, err: RequestValidationError) -> JSONResponse:
        first = err.errors()[0] if err.errors() else {}
        loc = [str(p) for p in first.get("loc", ()) if p not in ("path", "query", "body")]
        field = ".".join(loc)
        e = InvalidValueError(f"{field or 'request'}: {first.get('msg', 'invalid')}", field=field)
        return JSONResponse(e.body(), status_code=422)

    @api.exception_handler(HTTPException)
    async def _http_error(request: Request, err: HTTPException) -> JSONResponse:
        code = {404: "not_found", 405: "method"}.get(err.status_code, "bad_request")
        e = StudioError(str(err.detail), status=err.status_code, code=code)
        return JSONResponse(e.body(), status_code=err.status_code)

    async def body_of(request: Request) -> Any:
        raw = await request.body()
        if not raw:
            return {}
        try:
            return json.loads(raw)
        except (ValueError, RecursionError) as err:
            raise BadJsonError(f"body: not JSON ({err})") from None

    def png(data: bytes, headers: dict[str, str] | None = None) -> Response:
        return Response(content=data, media_type="image/png", headers={"Cache-Control": "no-store", **(headers or {})})

    # -- page ----------------------------------------------------------------------------------------
    @api.get("/")
    def index(request: Request) -> Response:
        page = STATIC_DIR / "index.html"
        response: Response = FileResponse(page) if page.is_file() else HTMLResponse(PLACEHOLDER)
        given = request.query_params.get("token")
        if given and token_matches(given, token):
            response.set_cookie(TOKEN_COOKIE, token, httponly=True, samesite="strict", path="/")
        response.headers["Cache-Control"] = "no-store"
        return response

    @api.get("/static/{path:path}")
    def static(path: str) -> Response:
        root = STATIC_DIR.resolve()
        target = (root / path).resolve()
        if root not in target.parents or not target.is_file():
            raise NotFoundError(f"no static file {path!r}", field="path")
        return FileResponse(target)

    # -- head and live -------------------------------------------------------------------------------
    @api.get("/api/head")
    def head() -> Any:
        return studio.head()

    @api.get("/api/state")
    def state() -> Any:
        return studio.state()

    def motion_route(path: str, model: type[Any], method: Any, status: int = 202) -> None:
        async def route(request: Request) -> Any:
            body = m.parse(model, await body_of(request))
            return JSONResponse(await run_in_threadpool(method, body), status_code=status)

        api.add_api_route(path, route, methods=["POST"], name=path)

    motion_route("/api/aus", m.SetAus, studio.set_aus)
    motion_route("/api/aus/clear", m.ClearAus, studio.clear_aus)
    motion_route("/api/express", m.Express, studio.express)
    motion_route("/api/gaze", m.Gaze, studio.gaze)
    motion_route("/api/neutral", m.Neutral, studio.neutral)
    motion_route("/api/alive", m.Alive, studio.alive)
    motion_route("/api/stop", m.Stop, studio.stop)
    motion_route("/api/hold", m.Hold, studio.set_hold, 200)
    motion_route("/api/estop", m.EStop, studio.estop)
    motion_route("/api/estop/clear", m.Empty, studio.clear_estop, 200)
    motion_route("/api/torque", m.OnOff, studio.torque, 200)
    motion_route("/api/servos/manual", m.OnOff, studio.set_manual, 200)
    motion_route("/api/calibrate/start", m.CalibrateStart, studio.calibrate_start, 200)
    motion_route("/api/calibrate/reply", m.CalibrateReply, studio.calibrate_reply, 200)
    motion_route("/api/calibration/apply", m.CalibrationApply, studio.calibration_apply, 200)
    motion_route("/api/record/start", m.RecordStart, studio.record_start, 200)
    motion_route("/api/record/stop", m.Empty, studio.record_stop, 200)
    motion_route("/api/scripts/check", m.ScriptBody, studio.script_check, 200)
    motion_route("/api/scripts/sample", m.ScriptSample, studio.script_sample, 200)
    motion_route("/api/play", m.Play, studio.play)

    @api.get("/api/record")
    def record_state() -> Any:
        return studio.record_state()

    @api.get("/api/twin/{which}.png")
    def twin(which: str) -> Response:
        image = studio.twin_png(which)
        return png(image.png, {"X-Twin-Seq": str(image.seq), "X-Twin-Frame": str(image.frame_index)})

    # -- servos --------------------------------------------------------------------------------------
    @api.get("/api/servos")
    def servos() -> Any:
        return studio.servos()

    def servo_route(suffix: str, model: type[Any], method: Any) -> None:
        async def route(servo_id: int, request: Request) -> Any:
            body = m.parse(model, await body_of(request))
            return await run_in_threadpool(method, servo_id, body)

        api.add_api_route(f"/api/servos/{{servo_id}}/{suffix}", route, methods=["POST"], name=suffix)

    servo_route("jog", m.Jog, studio.jog)
    servo_route("torque", m.OnOff, studio.servo_torque)
    servo_route("reboot", m.Empty, studio.reboot)

    # -- calibrate -----------------------------------------------------------------------------------
    @api.get("/api/calibrate")
    def calibrate_state() -> Any:
        return studio.calibrate_state()

    @api.get("/api/calibrate/plot/{role}.png")
    def calibrate_plot(role: str) -> Response:
        return png(studio.calibrate_plot(role))

    @api.get("/api/calibrate/twin.png")
    def calibrate_twin() -> Response:
        return png(studio.calibrate_twin())

    # -- author --------------------------------------------------------------------------------------
    @api.get("/api/scripts")
    def scripts() -> Any:
        return studio.script_list()

    @api.get("/api/scripts/{name:path}")  # (a name with "/" or ".." reaches check_name: 422, not a 404)
    def script_load(name: str) -> Any:
        return studio.script_load(name)

    @api.put("/api/scripts/{name:path}")
    async def script_save(name: str, request: Request) -> Any:
        body = m.parse(m.ScriptBody, await body_of(request))
        return await run_in_threadpool(studio.script_save, name, body)

    @api.post("/api/scripts/preview")
    async def script_preview(request: Request) -> Response:
        body = m.parse(m.ScriptPreview, await body_of(request))
        return png(await run_in_threadpool(studio.script_preview, body))

    # -- live socket ---------------------------------------------------------------------------------
    limiter = limiter or RateLimiter()

    @api.websocket("/api/ws")
    async def socket(websocket: WebSocket) -> None:
        await serve_socket(studio, websocket, limiter)

    return Gatekeeper(api, token, origins, limiter)
