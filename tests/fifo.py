"""A guard for tests of code that must refuse a FIFO rather than wait on it: a regression fails the test
instead of hanging the run."""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Callable
from pathlib import Path

import pytest


def settle(call: Callable[[], object], fifo: Path, timeout_s: float = 10.0) -> object:
    """What ``call`` returned, or the exception it raised. A call still waiting on ``fifo`` after ``timeout_s``
    (a regression) fails the test instead of hanging the run: a writer comes and goes, so the reader returns."""
    outcome: list[object] = []

    def run() -> None:
        try:
            outcome.append(call())
        except BaseException as err:  # handed to the test thread
            outcome.append(err)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(timeout_s)
    if thread.is_alive():
        with contextlib.suppress(OSError):
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        thread.join(timeout_s)
        pytest.fail(f"still waiting on the FIFO {fifo} after {timeout_s:g} s")
    return outcome[0]
