"""Errors of the network front end."""

from __future__ import annotations

from servoface.controller.errors import ControllerError


class NetworkError(ControllerError):
    """A Zenoh session, endpoint or key could not be used; the message says which and what to do."""


class MessageError(NetworkError):
    """A message was refused: unknown schema version, stale or out-of-order sequence, malformed body."""


class InsecureEndpointError(NetworkError):
    """A non-loopback endpoint without TLS and credentials, without --insecure."""
