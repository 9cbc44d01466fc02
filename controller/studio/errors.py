"""Errors of the studio: each carries the HTTP status, a short code and the field at fault, so every
refusal reaches the browser as one JSON shape (see API.md "Errors")."""

from __future__ import annotations

from typing import Any

from servoface.controller.errors import ControllerError


class StudioError(ControllerError):
    """A request the studio refuses. ``status`` is the HTTP status (4xx), ``field`` a dotted path or ""."""

    status = 400
    code = "bad_request"

    def __init__(self, message: str, *, field: str = "", status: int | None = None, code: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.field = field
        if status is not None:
            self.status = status
        if code is not None:
            self.code = code

    def body(self) -> dict[str, Any]:
        """The JSON error body; lone surrogates and other unencodable text escaped (always valid UTF-8)."""
        return {
            "error": {
                "status": self.status,
                "code": self.code,
                "field": _safe(self.field),
                "message": _safe(self.message),
            }
        }


def _safe(text: str) -> str:
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


class InvalidValueError(StudioError):
    """A value out of range, of the wrong type, or unknown (422)."""

    status = 422
    code = "invalid"


class BadJsonError(StudioError):
    """A body that is not a JSON object (400)."""

    status = 400
    code = "bad_json"


class UnauthorizedError(StudioError):
    status = 401
    code = "unauthorized"


class ForbiddenOriginError(StudioError):
    status = 403
    code = "forbidden_origin"


class NotFoundError(StudioError):
    status = 404
    code = "not_found"


class ConflictError(StudioError):
    """The request is fine but the head is not in a state to do it (e-stop latched, manual mode ...)."""

    status = 409
    code = "conflict"


class TooLargeError(StudioError):
    status = 413
    code = "too_large"


class RateLimitedError(StudioError):
    status = 429
    code = "rate_limited"
