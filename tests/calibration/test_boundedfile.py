"""The bounded reader every user-named text file goes through (calibration/boundedfile.py): the parts the
command-line tests cannot reach — a file that grows between the size check and the read, a stream a caller
allowed, a file exactly at the limit."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest
from servoface.calibration import boundedfile
from servoface.calibration.boundedfile import describe_size, read_bounded


class Refused(Exception):
    pass


def test_a_file_at_the_limit_is_read_and_one_byte_more_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "f.txt"
    path.write_bytes(b"x" * 1024)
    assert read_bounded(path, Refused, what="a test file", limit_bytes=1024) == b"x" * 1024
    path.write_bytes(b"x" * 1025)
    with pytest.raises(Refused, match=r"^1025 bytes; a test file is at most 1 KiB$"):
        read_bounded(path, Refused, what="a test file", limit_bytes=1024)


def test_a_file_that_grows_after_the_size_check_is_cut_at_the_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "growing.txt"
    path.write_bytes(b"x" * 5000)
    small = os.stat(path)
    fake = os.stat_result((small.st_mode, *small[1:6], 10, *small[7:]))  # st_size 10: as before it grew
    monkeypatch.setattr(boundedfile.os, "stat", lambda p: fake)
    monkeypatch.setattr(boundedfile.os, "fstat", lambda fd: fake)
    with pytest.raises(Refused, match=r"^more than 1 KiB and not at its end; a test file is at most 1 KiB$"):
        read_bounded(path, Refused, what="a test file", limit_bytes=1024)


@pytest.mark.skipif(not hasattr(os, "mkfifo") or not Path("/dev/zero").exists(), reason="POSIX devices and FIFOs")
def test_streams_only_when_the_caller_allows_them(tmp_path: Path) -> None:
    with pytest.raises(Refused, match=r"^a device, not a regular file; expected a test file$"):
        read_bounded("/dev/zero", Refused, what="a test file", limit_bytes=1024)
    with pytest.raises(Refused, match=r"^a device, not a regular file, a pipe or a terminal; expected a test file$"):
        read_bounded("/dev/zero", Refused, what="a test file", limit_bytes=1024, allow_stream=True)  # never a device
    with pytest.raises(Refused, match=r"^a directory, not a regular file"):
        read_bounded(tmp_path, Refused, what="a test file", allow_stream=True)  # never a stream
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(Refused, match=r"^a pipe \(FIFO\), not a regular file"):
        read_bounded(fifo, Refused, what="a test file")  # refused before it is opened: no wait for a writer

    def write() -> None:
        with fifo.open("wb") as fh:
            fh.write(b"hello world\n")

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    assert read_bounded(fifo, Refused, what="a test file", allow_stream=True) == b"hello world\n"
    writer.join(10)


def test_sizes_read_as_people_write_them() -> None:
    assert [describe_size(n) for n in (300, 2048, 16 * 2**20, 2_254_857_830)] == [
        "300 bytes",
        "2 KiB",
        "16 MiB",
        "2.1 GiB",
    ]


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="POSIX terminals")
def test_a_terminal_is_a_stream_and_reads_to_its_end_of_file() -> None:
    """``--input /dev/stdin`` typed at a terminal: a character device that is a TTY, read until Ctrl-D."""
    main, follower = os.openpty()
    try:
        os.write(main, b"hello\n\x04")  # a line, then Ctrl-D: end of file at the start of a line
        path = os.ttyname(follower)
        assert read_bounded(path, Refused, what="a test file", allow_stream=True) == b"hello\n"
        with pytest.raises(Refused, match=r"^a device, not a regular file; expected a test file$"):
            read_bounded(path, Refused, what="a test file")  # not where no stream is allowed
    finally:
        os.close(main)
        os.close(follower)
