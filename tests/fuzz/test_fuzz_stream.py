"""Stream messages — what `servoface stream` takes over UDP, TCP or a line stream (stdin, a file): 10^4
generated messages through `StreamSource.feed`, the one door every receiver hands each datagram or line to
(with and without a token guard); it never raises, every sampled frame is in range, every message is
counted. Then the receivers themselves over loopback sockets and a line stream: a batch of generated
messages (deep nesting, 400-digit integers, bytes that are not UTF-8, lines longer than the limit) and the
receiver thread is still running and takes the next good message."""

from __future__ import annotations

import io
import json
import math
import os
import socket
import time
from collections.abc import Callable
from typing import Any

from hypothesis import Phase, given, settings
from hypothesis import strategies as st
from servoface.controller.inputs import LineReceiver, MessageDecoder, StreamSource, TcpReceiver, UdpReceiver
from servoface.controller.inputs.admission import StreamGuard

from tests.fuzz.strategies import HUGE, fuzz_settings, values, weird_text

N = int(os.environ.get("SERVOFACE_FUZZ_EXAMPLES", "10000"))
TOKEN = "s3cret-token"
DECODER = MessageDecoder("human", mirror=True)  # built once: its tables are read-only


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


_names = (
    st.sampled_from(
        ["AU12", "AU12L", "AU4", "AU99", "au1", "AU１２", " AU12", "mouthSmileLeft", "jawOpen", "eyeBlinkRight", ""]
    )
    | weird_text
)
_numbers = st.floats(-2, 2) | st.floats(allow_nan=True, allow_infinity=True) | HUGE | st.integers(-5, 5)
_odd = st.sampled_from([None, True, "0.5", [], {}, [0.5], {"x": 1}, "\x1b[2J", "\ud800"])
_fields = st.fixed_dictionaries(
    {},
    optional={
        "t": _numbers | _odd,
        "timestamp_ms": _numbers | _odd,
        "aus": st.dictionaries(_names, _numbers | _odd, max_size=4) | values,
        "blendshapes": st.dictionaries(_names, _numbers | _odd, max_size=4) | _odd,
        "head": st.dictionaries(
            st.sampled_from(["yaw_deg", "pitch_deg", "roll_deg", "matrix", "x"]), _numbers | _odd, max_size=3
        ),
        "confidence": _numbers | _odd,
        "face_id": _numbers | _odd,
        "token": st.sampled_from([TOKEN, "wrong", ""]) | _odd,
    },
)


def _dump(obj: Any) -> str:
    try:
        return json.dumps(obj, allow_nan=True)
    except (TypeError, ValueError):  # a frozenset, a huge int beyond str() limits: send its repr instead
        return repr(obj)[:4000]


SPECIAL: dict[str, str | bytes] = {  # by name: hypothesis shows the name, not 100 kB of brackets
    "nested 1000": '{"aus": ' + "[" * 1000 + "]" * 1000 + "}",
    "open 100000": "[" * 100_000,
    "400 digits": '{"aus": {"AU12": ' + "9" * 400 + "}}",
    "1e999": '{"aus": {"AU12": 1e999}}',
    "NaN": '{"aus": {"AU12": NaN}}',
    "t -1e308": '{"t": -1e308, "aus": {"AU12": 0.5}}',
    "surrogate": '{"aus": {"\\ud800": 0.5}}',
    "escape": '{"aus": {"\\u001b[31mAU12": 0.5}}',
    "not utf-8": b"\xff\xfe\x00{",
    "three in one": '{"aus": {"AU12": 0.5}}' * 3,
    "70 kB": "x" * 70_000,
    "nested 2000 in aus": '{"aus": ' + "[" * 2000 + "]" * 2000 + "}",
    "dict 300 deep": '{"a": ' * 300 + "1" + "}" * 300,
}


def _dump(obj: Any) -> str:
    try:
        return json.dumps(obj, allow_nan=True)
    except (TypeError, ValueError, RecursionError):  # a frozenset, a huge nest: its repr instead
        return repr(obj)[:4000]


raw_messages = st.one_of(
    _fields.map(_dump),
    _fields.map(lambda m: _dump(m).encode("utf-8", "surrogatepass")),
    values.map(_dump),
    st.text(max_size=40),
    st.binary(max_size=60),
    st.sampled_from(sorted(SPECIAL)).map(SPECIAL.__getitem__),
)


def _valid(frame: Any) -> bool:
    return all(isinstance(v, float) and math.isfinite(v) and -1.0 <= v <= 1.0 for v in frame.aus.values())


@fuzz_settings(N)
@given(st.lists(raw_messages, min_size=1, max_size=2), st.booleans(), st.sampled_from([0.0, 0.01, 0.3, 5.0]))
def test_any_message_is_a_frame_or_a_counted_reject(raw: list[str | bytes], guarded: bool, gap_s: float) -> None:
    clock = FakeClock()
    guard = StreamGuard(token=TOKEN) if guarded else None
    src = StreamSource(DECODER, clock=clock, guard=guard)
    for k, item in enumerate(raw):
        src.feed(item, where="udp 127.0.0.1:5", client=("udp", ("127.0.0.1", 5)))
        clock.now += gap_s
        assert _valid(src.sample(k * gap_s))
    s = src.stats
    assert s.messages == len(raw)
    assert s.good + s.bad + s.out_of_order <= len(raw)


def _wait_for(cond: Callable[[], bool], timeout_s: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


GOOD = b'{"aus": {"AU12": 0.5}}'


def _survives(src: StreamSource, receiver: Any, send: Callable[[bytes], None], batch: list[bytes], good: bytes) -> None:
    """After the batch, the receiver is alive and a good message still gets through (resent until it does:
    a loaded machine may drop a datagram)."""
    for item in batch:
        send(item)
    good_before = src.stats.good

    def through() -> bool:
        send(good)
        return src.stats.good > good_before

    assert _wait_for(through), src.stats
    assert receiver.running


def _as_bytes(item: str | bytes) -> bytes:
    return item if isinstance(item, bytes) else item.encode("utf-8", "surrogatepass")


SOCKET_BATCHES = 3  # the first generated batch is the simplest one; the others are random (derandomized)


@settings(fuzz_settings(SOCKET_BATCHES), phases=[Phase.generate])  # real sockets: no shrinking
@given(st.lists(raw_messages, min_size=150, max_size=150))
def test_udp_and_tcp_receivers_survive_any_batch(batch: list[str | bytes]) -> None:
    messages = [_as_bytes(m) for m in batch + list(SPECIAL.values())]
    src = StreamSource(MessageDecoder("human"), guard=StreamGuard(rate_hz=1e5, burst=1e5))
    with UdpReceiver(src, "127.0.0.1", 0) as udp, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        datagrams = [m[:60_000] for m in messages]  # a datagram's limit; longer is tested over TCP
        _survives(src, udp, lambda b: tx.sendto(b, udp.address) and None, datagrams, GOOD)
    src = StreamSource(MessageDecoder("human"), guard=StreamGuard(rate_hz=1e5, burst=1e5))
    with TcpReceiver(src, "127.0.0.1", 0) as tcp:
        with socket.create_connection(tcp.address, timeout=10) as conn:
            lines = [m.replace(b"\n", b" ") + b"\n" for m in messages] + [b"y" * 100_000 + b"\n"]
            _survives(src, tcp, conn.sendall, lines, GOOD + b"\n")


@settings(fuzz_settings(SOCKET_BATCHES), phases=[Phase.generate])
@given(st.lists(raw_messages, min_size=150, max_size=150))
def test_the_line_receiver_reads_past_any_line(batch: list[str | bytes]) -> None:
    batch = batch + list(SPECIAL.values())
    text = "".join(
        (m.decode("utf-8", "replace") if isinstance(m, bytes) else m).replace("\n", " ").replace("\r", " ") + "\n"
        for m in batch
    )
    src = StreamSource(MessageDecoder("human"))
    receiver = LineReceiver(src, io.StringIO(text + GOOD.decode() + "\n"), where="stdin").start()
    assert receiver.eof.wait(60.0)
    receiver.close()
    assert src.stats.messages == sum(1 for line in text.split("\n") if line.strip()) + 1  # as a file reads it
    assert src.stats.good >= 1  # the last, good line was taken
