"""Run the `servoface` command line in-process for a test: exit status, stdout and stderr of that run only."""

from __future__ import annotations

import pytest
from servoface.controller.cli import main


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    capsys.readouterr()  # what earlier steps printed is not this run's
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err
