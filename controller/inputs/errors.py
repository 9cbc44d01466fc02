"""Errors of the input adapters (files, streams): a bad row, message or field names where it is."""

from __future__ import annotations

from servoface.controller.errors import FrameError


class InputError(FrameError):
    """Outside face data is malformed: the message names the file, line, column or message field."""
