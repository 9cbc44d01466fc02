"""USB-serial latency timer (FTDI, e.g. U2D2): detect the 16 ms default and say how to fix it.

The FTDI chip holds received bytes until its buffer fills or its latency timer expires (default 16 ms),
so every status packet can arrive up to 16 ms late: a ~60 Hz ceiling whatever the baud. Linux exposes the
timer at ``/sys/bus/usb-serial/devices/<tty>/latency_timer``. The SDK's reply window is
``tx_time + 2 * LATENCY_TIMER + 2 ms``, so the driver sets its latency constant from what it finds here.
"""

from __future__ import annotations

import os
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

SYSFS_USB_SERIAL = Path("/sys/bus/usb-serial/devices")
RECOMMENDED_LATENCY_MS = 1
SDK_DEFAULT_LATENCY_MS = 16
PTY_LATENCY_MS = 16  # the far end is a thread or process that must be scheduled (and get the GIL)


class UsbLatencyWarning(UserWarning):
    """The USB-serial adapter's latency timer is high (reads stall up to that many ms)."""


@dataclass(frozen=True)
class LatencyTimer:
    """The OS latency timer of a serial port, when the OS exposes one."""

    port: str
    sysfs_path: Path | None  # None when the port has no latency timer (ttyACM, pty, not Linux)
    value_ms: int | None

    @property
    def is_high(self) -> bool:
        return self.value_ms is not None and self.value_ms > RECOMMENDED_LATENCY_MS

    def advice(self) -> str:
        """How to lower the timer (empty when it is already low or absent)."""
        if not self.is_high or self.sysfs_path is None or self.value_ms is None:
            return ""
        tty = self.sysfs_path.parent.name
        return (
            f"{self.port}: USB latency timer is {self.value_ms} ms, so every reply can stall up to "
            f"{self.value_ms} ms (~{1000 // max(1, self.value_ms)} Hz ceiling). Fix now: "
            f"echo 1 | sudo tee {self.sysfs_path}  (or: setserial /dev/{tty} low_latency). "
            "Make it permanent with a udev rule, e.g. /etc/udev/rules.d/99-dynamixel.rules: "
            'ACTION=="add", SUBSYSTEM=="usb-serial", DRIVER=="ftdi_sio", ATTR{latency_timer}="1"'
        )


def read_latency_timer(port: str, sysfs_root: Path = SYSFS_USB_SERIAL) -> LatencyTimer:
    """Find and read the latency timer of ``port`` (``/dev/ttyUSB0`` or a symlink to it)."""
    if not sys.platform.startswith("linux") and sysfs_root == SYSFS_USB_SERIAL:
        return LatencyTimer(port, None, None)
    tty = os.path.basename(os.path.realpath(port))
    path = sysfs_root / tty / "latency_timer"
    try:
        value = int(path.read_text(encoding="ascii").strip())
    except (OSError, ValueError):
        return LatencyTimer(port, None, None)
    return LatencyTimer(port, path, value)


def warn_if_high(timer: LatencyTimer) -> None:
    """Emit a `UsbLatencyWarning` with the fix when the timer is above 1 ms."""
    if timer.is_high:
        warnings.warn(timer.advice(), UsbLatencyWarning, stacklevel=3)


def sdk_latency_ms(timer: LatencyTimer, is_pty: bool) -> int:
    """The SDK latency constant to use for this port: the OS timer when known (plus 1 ms margin),

    16 ms (the SDK default) for an unknown real device and for a pty (another process or thread must be
    scheduled to answer; on a loaded machine 8 ms proved too short).
    """
    if timer.value_ms is not None:
        return timer.value_ms + 1 if timer.value_ms <= RECOMMENDED_LATENCY_MS else timer.value_ms
    return PTY_LATENCY_MS if is_pty else SDK_DEFAULT_LATENCY_MS
