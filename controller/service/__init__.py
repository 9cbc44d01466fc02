"""The head service: one runtime owns a head (pipeline, driver, the loop thread); every front end (CLI,
`Face`, studio, speech, network) drives it with validated commands on named tracks and watches it through
bounded observer queues. See the README section "The head service"."""

from servoface.controller.service.clock import ServiceClock
from servoface.controller.service.errors import (
    CommandFailedError,
    EStopLatchedError,
    ServiceClosedError,
    ServiceError,
)
from servoface.controller.service.handles import CommandHandle, PlaybackEvent, Status
from servoface.controller.service.observers import FrameSummary, ServiceEvent, Subscription
from servoface.controller.service.opening import OpenedHead, head_calibration, open_head
from servoface.controller.service.service import HeadService, ServiceStatus, StopReport
from servoface.controller.service.slots import TrackView
from servoface.controller.service.tracks import DEFAULT_PRIORITY, DEFAULT_TRACKS, Mixer, TrackSpec

__all__ = [
    "DEFAULT_PRIORITY",
    "DEFAULT_TRACKS",
    "CommandFailedError",
    "CommandHandle",
    "EStopLatchedError",
    "FrameSummary",
    "HeadService",
    "Mixer",
    "OpenedHead",
    "PlaybackEvent",
    "ServiceClock",
    "ServiceClosedError",
    "ServiceError",
    "ServiceEvent",
    "ServiceStatus",
    "Status",
    "StopReport",
    "Subscription",
    "TrackSpec",
    "TrackView",
    "head_calibration",
    "open_head",
]
