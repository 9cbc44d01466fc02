"""The studio: pose, puppeteer, calibrate and author a head in a browser, with the twin in the loop.

`servoface studio` starts the head service and serves a FastAPI app (API.md beside this file) and its
static front end (``static/``); every command goes through the service and its twin gate."""

from servoface.controller.studio.errors import StudioError
from servoface.controller.studio.server import StudioServer
from servoface.controller.studio.studio import Studio, StudioOptions

__all__ = ["Studio", "StudioError", "StudioOptions", "StudioServer"]
