"""``--fast-sync-read`` and ``--position-sentinel`` from the command line, checked from the emulator's side of
a real pty (the chain in its own process, `servoface emulate --state-file`):

- ``--fast-sync-read off`` puts no Fast Sync Read (0x8A) on the wire, not even the start-up probe; the default
  (``auto``) probes and reads positions with it;
- ``--position-sentinel off`` writes nothing to Indirect Address and reads Present Position directly (at 132);
  the default maps the sentinel at start-up and reads positions through it (at 224);
- a bad value of either is refused by argparse before anything is opened."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest
from servoface.controller.cli import main

from tests.integration.safe_stop_rig import bench, goals_outside_limits, torque_on_ids

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")

FAST_SYNC_READ, SYNC_READ = "0x8A", "0x82"
SENTINEL_DATA, PRESENT_POSITION = "224", "132"


def _play(tmp_path: Path, flags: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    """`servoface play happiness` on the pty with ``flags``; the emulator's final state (the run ended well:
    exit 0, every servo torque off, no goal outside its limits)."""
    with bench(tmp_path) as b:
        status = main(["play", "happiness", "--port", b.port, "--hold", "0.2", *flags])
        out, err = capsys.readouterr()
        state = b.final_state()
    assert status == 0, out + err
    assert torque_on_ids(state) == [] and goals_outside_limits(state) == []
    return state


@pytest.mark.parametrize("flags, fast_reads", [(["--fast-sync-read", "off"], False), ([], True)])
def test_fast_sync_read_decides_what_read_goes_on_the_wire(
    tmp_path: Path, flags: list[str], fast_reads: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    counts = _play(tmp_path, flags, capsys)["instruction_counts"]
    if fast_reads:  # the probe, then every cycle's position read
        assert counts.get(FAST_SYNC_READ, 0) >= 10, counts
    else:
        assert FAST_SYNC_READ not in counts and counts.get(SYNC_READ, 0) >= 10, counts


@pytest.mark.parametrize("flags, sentinel", [(["--position-sentinel", "off"], False), ([], True)])
def test_position_sentinel_decides_how_positions_are_read_on_the_wire(
    tmp_path: Path, flags: list[str], sentinel: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    state = _play(tmp_path, flags, capsys)
    reads = state["read_addresses"]
    if sentinel:  # one map per servo at configure (30 servos), then every plain cycle's read at 224
        assert state["indirect_address_writes"] >= 30, state["indirect_address_writes"]
        assert reads.get(SENTINEL_DATA, 0) >= 10, reads
    else:
        assert state["indirect_address_writes"] == 0
        assert SENTINEL_DATA not in reads and reads.get(PRESENT_POSITION, 0) >= 10, reads


@pytest.mark.parametrize("flag, choice", [("--fast-sync-read", "auto"), ("--position-sentinel", "on")])
def test_a_bad_value_is_refused_before_opening(flag: str, choice: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["play", "happiness", "--emulate", flag, "maybe"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert flag in err and "maybe" in err and choice in err
