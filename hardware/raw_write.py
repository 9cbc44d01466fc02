"""One ``os.write`` for a packet to pyserial's own posix port, instead of pyserial's ``write`` (the bus's
`_WindowedPort.writePort` on a port whose reads already go to its fd, see `_WindowedPort._read_raw`).

pyserial's ``write`` with no write timeout (how the SDK opens the port) calls ``os.write`` and then blocks in
``select`` until the port is writable again, after every write: two system calls and a ``Timeout`` object
per instruction packet, two packets per frame. Here a packet the kernel takes whole is one ``os.write``;
anything else (the kernel's buffer full: a partial write or EAGAIN) waits until the port is writable and
hands the rest to pyserial's own ``write``. The same bytes in the same order, the same errors (an OSError is
pyserial's ``SerialException("write failed: ...")``, a packet that is no byte sequence pyserial's own
``to_bytes`` error); what moves is only when a full buffer is waited for (before the next write instead of
after this one): tests/hardware/test_bus_raw_write.py.
"""

from __future__ import annotations

import errno
import os
import select
from typing import Any

import serial
from serial.serialutil import to_bytes

_RETRY = (errno.EAGAIN, errno.EALREADY, errno.EWOULDBLOCK, errno.EINPROGRESS, errno.EINTR)  # pyserial's


def write_raw(ser: Any, packet: Any) -> int:
    """Write ``packet`` (a list of ints or bytes) to the open posix pyserial ``ser``; returns its length."""
    data = to_bytes(packet)
    try:
        n = os.write(ser.fd, data)
    except OSError as err:
        if err.errno not in _RETRY:
            raise serial.SerialException(f"write failed: {err}") from err
        n = 0
    if n == len(data):
        return n
    select.select([], [ser.fd], [])  # wait for room, as pyserial's write would have after its last one
    return n + int(ser.write(data[n:]))
