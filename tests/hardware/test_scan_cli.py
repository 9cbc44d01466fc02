"""`servoface scan` against an emulated chain served on a pty (as from `servoface emulate`)."""

from __future__ import annotations

import pytest
from servoface.controller.cli import main
from servoface.hardware.bus import ids_from_spec, open_bus
from servoface.hardware.emulator import ServoChain
from servoface.hardware.scan import scan


def test_scan_prints_a_table_of_the_chain(capsys: pytest.CaptureFixture[str]) -> None:
    chain = ServoChain.create(ids=[1, 2, 5], model="XL330-M288", baud=1_000_000, wire_time=False)
    chain.faults.inject(5, "overload")
    try:
        status = main(["scan", "--port", chain.serve_pty(), "--ids", "1-6"])
    finally:
        chain.close()
    out = capsys.readouterr().out
    assert status == 0
    lines = [line.split() for line in out.splitlines() if line and not line.startswith(("#", "  id"))]
    assert [row[0] for row in lines] == ["1", "2", "5"]
    assert all(row[1] == "1200" and row[2] == "XL330-M288" for row in lines)
    assert "OVERLOAD" in out.splitlines()[-1] and "none" in out.splitlines()[-2]


def test_scan_reports_an_empty_chain_and_bad_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    chain = ServoChain.create(ids=[1], model="XL430-W250", baud=57_600, wire_time=False)
    try:
        assert main(["scan", "--port", chain.serve_pty(), "--ids", "1-2"]) == 1  # wrong baud: silence
        assert main(["scan", "--port", chain.serve_pty(), "--baud", "57600", "--ids", "x"]) == 2
    finally:
        chain.close()
    assert "--ids" in capsys.readouterr().err
    assert main(["scan", "--port", "/dev/does-not-exist"]) == 2  # a port that does not exist: bad input
    assert "cannot open" in capsys.readouterr().err


def test_broadcast_scan_in_process() -> None:
    chain = ServoChain.create(ids=[3, 4], model="XM430-W350", baud=1_000_000, wire_time=False)
    with open_bus("emulator", chain=chain) as bus:
        found = scan(bus)
    assert [(r.servo_id, r.model_name, r.hardware_error) for r in found] == [
        (3, "XM430-W350", 0),
        (4, "XM430-W350", 0),
    ]


def test_id_spec_parsing() -> None:
    assert ids_from_spec("1-3, 7") == [1, 2, 3, 7]
    with pytest.raises(ValueError, match="outside 0..252"):
        ids_from_spec("250-260")


def test_scan_all_bauds_finds_a_factory_fresh_chain(capsys: pytest.CaptureFixture[str]) -> None:
    chain = ServoChain.create(ids=[1], model="XL430-W250", baud=57_600, wire_time=False)
    try:
        assert main(["scan", "--port", chain.serve_pty(), "--baud", "all", "--ids", "1"]) == 0
    finally:
        chain.close()
    out, err = capsys.readouterr()
    assert "at 57600 bps, ids 1: 1 servo(s)" in out and "XL430-W250" in out
    assert "# trying 57600 bps (1 of " in err  # progress on stderr, a line per baud rate (seconds each)
    with pytest.raises(SystemExit):
        main(["scan", "--port", "/dev/null", "--baud", "fast"])
