"""``--fast-sync-read`` from the command line, checked from the emulator's side of a real pty (the chain in its
own process, `servoface emulate --state-file`): ``off`` puts no Fast Sync Read (0x8A) on the wire, not even
the start-up probe; the default (``auto``) probes and reads positions with it; a bad value is refused by
argparse before anything is opened."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from servoface.controller.cli import main

from tests.integration.safe_stop_rig import bench, goals_outside_limits, torque_on_ids

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")

FAST_SYNC_READ, SYNC_READ = "0x8A", "0x82"


@pytest.mark.parametrize("flag, fast_reads", [(["--fast-sync-read", "off"], False), ([], True)])
def test_the_flag_decides_what_read_goes_on_the_wire(
    tmp_path: Path, flag: list[str], fast_reads: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    with bench(tmp_path) as b:
        status = main(["play", "happiness", "--port", b.port, "--hold", "0.2", *flag])
        out, err = capsys.readouterr()
        state = b.final_state()
    assert status == 0, out + err
    counts = state["instruction_counts"]
    assert torque_on_ids(state) == [] and goals_outside_limits(state) == []
    if fast_reads:  # the probe, then every cycle's position read
        assert counts.get(FAST_SYNC_READ, 0) >= 10, counts
    else:
        assert FAST_SYNC_READ not in counts and counts.get(SYNC_READ, 0) >= 10, counts


def test_a_bad_value_is_refused_before_opening(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["play", "happiness", "--emulate", "--fast-sync-read", "maybe"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--fast-sync-read" in err and "maybe" in err and "auto" in err
