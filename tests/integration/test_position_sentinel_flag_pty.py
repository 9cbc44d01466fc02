"""``--position-sentinel`` from the command line, checked from the emulator's side of a real pty (the chain in
its own process, `servoface emulate --state-file`): ``off`` writes nothing to Indirect Address and reads
Present Position directly (at 132); the default maps the sentinel at start-up and reads positions through it
(at 224); a bad value is refused by argparse before anything is opened."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from servoface.controller.cli import main

from tests.integration.safe_stop_rig import bench, goals_outside_limits, torque_on_ids

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")

SENTINEL_DATA, PRESENT_POSITION = "224", "132"


@pytest.mark.parametrize("flag, sentinel", [(["--position-sentinel", "off"], False), ([], True)])
def test_the_flag_decides_how_positions_are_read_on_the_wire(
    tmp_path: Path, flag: list[str], sentinel: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    with bench(tmp_path) as b:
        status = main(["play", "happiness", "--port", b.port, "--hold", "0.2", *flag])
        out, err = capsys.readouterr()
        state = b.final_state()
    assert status == 0, out + err
    assert torque_on_ids(state) == [] and goals_outside_limits(state) == []
    reads = state["read_addresses"]
    if sentinel:  # one map per servo at configure (30 servos), then every plain cycle's read at 224
        assert state["indirect_address_writes"] >= 30, state["indirect_address_writes"]
        assert reads.get(SENTINEL_DATA, 0) >= 10, reads
    else:
        assert state["indirect_address_writes"] == 0
        assert SENTINEL_DATA not in reads and reads.get(PRESENT_POSITION, 0) >= 10, reads


def test_a_bad_value_is_refused_before_opening(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["play", "happiness", "--emulate", "--position-sentinel", "maybe"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--position-sentinel" in err and "maybe" in err and "on" in err
