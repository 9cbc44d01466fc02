"""USB latency timer detection and advice (a fake sysfs tree; no device needed)."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
from servoface.hardware.dynamixel_bus import DynamixelBus
from servoface.hardware.latency import UsbLatencyWarning, read_latency_timer, sdk_latency_ms, warn_if_high


def _sysfs(tmp_path: Path, tty: str, value: str) -> Path:
    root = tmp_path / "sys"
    (root / tty).mkdir(parents=True)
    (root / tty / "latency_timer").write_text(value)
    return root


def test_high_timer_warns_with_the_fix(tmp_path: Path) -> None:
    root = _sysfs(tmp_path, "ttyUSB0", "16\n")
    timer = read_latency_timer("/dev/ttyUSB0", sysfs_root=root)
    assert timer.value_ms == 16 and timer.is_high
    with pytest.warns(UsbLatencyWarning, match=r"echo 1 \| sudo tee .*ttyUSB0/latency_timer") as rec:
        warn_if_high(timer)
    assert "udev" in str(rec[0].message) and "low_latency" in str(rec[0].message)
    assert sdk_latency_ms(timer, is_pty=False) == 16


def test_low_timer_is_quiet(tmp_path: Path) -> None:
    timer = read_latency_timer("/dev/ttyUSB1", sysfs_root=_sysfs(tmp_path, "ttyUSB1", "1"))
    assert not timer.is_high and timer.advice() == ""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_if_high(timer)
    assert sdk_latency_ms(timer, is_pty=False) == 2


def test_symlinked_port_resolves_to_its_tty(tmp_path: Path) -> None:
    root = _sysfs(tmp_path, "ttyUSB3", "4")
    link = tmp_path / "by-id-u2d2"
    link.symlink_to("/dev/ttyUSB3")
    assert read_latency_timer(str(link), sysfs_root=root).value_ms == 4


def test_no_timer_for_ptys_and_acm(tmp_path: Path) -> None:
    timer = read_latency_timer("/dev/ttyACM0", sysfs_root=tmp_path)
    assert timer.value_ms is None and not timer.is_high
    assert sdk_latency_ms(timer, is_pty=True) == 16
    assert sdk_latency_ms(timer, is_pty=False) == 16


def test_bus_uses_its_own_latency_constant_for_the_reply_window() -> None:
    import dynamixel_sdk

    bus = DynamixelBus("/dev/null-not-opened", latency_timer_ms=3, warn_latency=False)
    port = bus._port
    port.tx_time_per_byte = 0.01
    port.setPacketTimeout(100)
    assert port.packet_timeout == pytest.approx(0.01 * 100 + 2 * 3 + 2)
    assert dynamixel_sdk.port_handler.LATENCY_TIMER == 16  # the SDK global is left alone


def test_reply_window_runs_on_a_monotonic_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    import time

    bus = DynamixelBus("/dev/null-not-opened", latency_timer_ms=1, warn_latency=False)
    port = bus._port
    port.setPacketTimeout(0)
    monkeypatch.setattr(time, "time", lambda: 1e12)  # a wall-clock step must not end the window
    assert not port.isPacketTimeout()


def test_reply_window_stays_open_while_bytes_are_waiting() -> None:
    from servoface.hardware.emulator import ServoChain

    chain = ServoChain.create(ids=[1], wire_time=False)
    bus = DynamixelBus(chain, latency_timer_ms=0)
    bus.open()
    port = bus._port
    port.writePort(bytes.fromhex("FFFFFD0001030001194E"))  # ping id 1 (e-manual CRC)
    port.setPacketTimeoutMillis(-1.0)  # already expired, as after a long deschedule
    assert port.getBytesAvailable() > 0 and not port.isPacketTimeout()
    port.clearPort()
    assert port.isPacketTimeout()
    bus.close()


def test_window_extension_is_bounded() -> None:
    from servoface.hardware.dynamixel_bus import MAX_WINDOW_EXTENSION_MS
    from servoface.hardware.emulator import ServoChain

    chain = ServoChain.create(ids=[1], wire_time=False)
    bus = DynamixelBus(chain, latency_timer_ms=0)
    bus.open()
    port = bus._port
    port.writePort(bytes.fromhex("FFFFFD0001030001194E"))
    port.setPacketTimeoutMillis(-(MAX_WINDOW_EXTENSION_MS + 1))  # expired long ago: bytes do not matter now
    assert port.getBytesAvailable() > 0 and port.isPacketTimeout()
    bus.close()
