"""Typed request bodies (pydantic, strict, unknown keys refused) for the HTTP routes and the WebSocket
messages alike, and the translation of their errors into :class:`InvalidValueError` naming the field."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator
from servoface.controller.studio.errors import BadJsonError, InvalidValueError

MAX_AUS = 64
MAX_REASON = 200
MAX_SCRIPT_CHARS = 512 * 1024

Seconds = Annotated[float, Field(ge=0.0, le=10.0)]
Unit = Annotated[float, Field(ge=-1.0, le=1.0)]
Tick = Annotated[int, Field(ge=0, le=4095)]


class Body(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


class SetAus(Body):
    aus: dict[str, float] = Field(max_length=MAX_AUS)
    transition_s: Seconds = 0.1
    merge: bool = True

    @field_validator("aus")
    @classmethod
    def _finite(cls, value: dict[str, float]) -> dict[str, float]:
        for name, v in value.items():
            if not math.isfinite(v):
                raise ValueError(f"{name}: expected a finite number, got {v!r}")
        return value


class ClearAus(Body):
    names: list[str] | None = Field(default=None, max_length=MAX_AUS)
    transition_s: Seconds = 0.3


class Express(Body):
    name: str = Field(max_length=100)
    intensity: Annotated[float, Field(ge=0.0, le=1.0)] = 1.0
    transition_s: Seconds = 0.5
    hold_s: Annotated[float, Field(ge=0.0, le=3600.0)] = 1.0
    track: Literal["face", "studio"] = "face"


class Gaze(Body):
    point_mm: Annotated[list[float], Field(min_length=3, max_length=3)] | None = None
    pad: Annotated[list[Unit], Field(min_length=2, max_length=2)] | None = None

    @field_validator("point_mm")
    @classmethod
    def _near(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(abs(v) > 10_000.0 for v in value):
            raise ValueError("expected a point within 10 m of the head (mm)")
        return value


class Neutral(Body):
    transition_s: Seconds = 0.6


class Alive(Body):
    blink: bool | None = None
    idle: bool | None = None


class Hold(Body):
    hold: bool


class EStop(Body):
    reason: str = Field(default="studio", max_length=MAX_REASON)


class Empty(Body):
    pass


class OnOff(Body):
    on: bool


class Stop(Body):
    track: str = Field(max_length=40)
    hold: bool = False
    release_s: Seconds = 0.3


class Jog(Body):
    delta_tick: Annotated[int, Field(ge=-4095, le=4095)] | None = None
    goal_tick: Tick | None = None


class CalibrateStart(Body):
    roles: list[Annotated[str, Field(max_length=64)]] | None = Field(default=None, max_length=256)
    points: Annotated[int, Field(ge=0, le=20)] = 3
    free_points: bool = False
    curve: Literal["linear", "piecewise_linear", "pchip"] | None = None
    out: str = Field(default="", max_length=128)
    apply: bool = True  # the saved calibration drives the running head at once (no restart)


class RecordStart(Body):
    transport: Literal["udp", "tcp"] = "udp"
    port: Annotated[int, Field(ge=0, le=65535)] = 0  # 0: a free one (the answer says which)
    tolerance: Annotated[float, Field(gt=0.0, le=0.5)] = 0.01
    follow: bool = True  # the head follows the stream live on the "stream" track while it records


class CalibrationApply(Body):
    file: str = Field(max_length=128)


class CalibrateReply(Body):
    action: Literal["capture", "jog", "goto", "goto_suggested", "relax", "finish", "abort"]
    target: float | None = None
    delta_tick: Annotated[int, Field(ge=-4095, le=4095)] | None = None
    tick: Tick | None = None


class ScriptBody(Body):
    document: dict[str, Any] | None = None
    toml: str | None = Field(default=None, max_length=MAX_SCRIPT_CHARS)


class ScriptSample(ScriptBody):
    fps: Annotated[float, Field(gt=0.0, le=100.0)] = 20.0


class ScriptPreview(ScriptBody):
    t_s: Annotated[float, Field(ge=0.0, le=86_400.0)] = 0.0
    which: Literal["achievable", "target"] = "achievable"


class Play(ScriptBody):
    name: str | None = Field(default=None, max_length=128)
    track: str = Field(default="face", max_length=40)
    loop: bool = False


class Subscribe(Body):
    twin: bool | None = None
    target: bool | None = None
    telemetry: bool | None = None
    frames: bool | None = None


M = TypeVar("M", bound=BaseModel)


def parse(model: type[M], data: Any, *, where: str = "") -> M:
    """``data`` (a decoded JSON value) as ``model``, or InvalidValueError naming the first bad field."""
    if not isinstance(data, dict):
        raise BadJsonError(f"{where or 'body'}: expected a JSON object, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise invalid(err, where) from None


def invalid(err: ValidationError, where: str = "") -> InvalidValueError:
    first = err.errors(include_url=False)[0]
    path = ".".join(str(p) for p in first.get("loc", ()))
    field = f"{where}.{path}" if where and path else (path or where)
    given = first.get("input")
    shown = repr(given)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    kind = first.get("type", "")
    message = "unknown key" if kind == "extra_forbidden" else first.get("msg", "invalid")
    return InvalidValueError(f"{field or 'body'}: {message} (got {shown})", field=field)
