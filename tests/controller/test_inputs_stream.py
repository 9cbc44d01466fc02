"""Live stream source: smoothing, dropout policy and validation on an injected clock; UDP/TCP/line receivers
on loopback (bounded in count and time); the stream end to end through the pipeline on the emulator."""

from __future__ import annotations

import io
import json
import math
import random
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.controller.cli import main as cli_main
from servoface.controller.face import Face
from servoface.controller.inputs import (
    AUSmoother,
    InputError,
    LineReceiver,
    MessageDecoder,
    OneEuroFilter,
    StreamSource,
    TcpReceiver,
    UdpReceiver,
)
from servoface.controller.inputs.admission import StreamGuard
from servoface.controller.inputs.follow import follow
from servoface.controller.inputs.transports import check_host, parse_address
from servoface.controller.performance import play_timeline


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _wait_for(cond: Callable[[], bool], timeout_s: float = 3.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.005)
    return cond()


# -- smoothing --
def test_one_euro_reduces_jitter_and_stays_in_range() -> None:
    rng = random.Random(3)
    f = OneEuroFilter(min_cutoff_hz=1.0, beta=0.0)
    raw = [min(1.0, max(0.0, 0.5 + rng.uniform(-0.1, 0.1))) for _ in range(200)]
    out = [f(x, k / 50) for k, x in enumerate(raw)]
    spread = lambda xs: max(xs) - min(xs)  # noqa: E731
    assert spread(out[100:]) < 0.4 * spread(raw[100:])
    g = OneEuroFilter(min_cutoff_hz=1.0, beta=1.0)
    step = [g(0.0 if k < 5 else 1.0, k / 50) for k in range(60)]
    assert all(0.0 <= v <= 1.0 for v in step) and all(b >= a for a, b in zip(step, step[1:], strict=False))
    assert step[-1] > 0.95  # it gets there (the speed term opens the cutoff)
    assert g(1.0, 59 / 50) == step[-1]  # same instant: unchanged


def test_smoother_eases_a_vanished_au_to_zero_and_rejects_bad_params() -> None:
    s = AUSmoother(min_cutoff_hz=2.0, beta=0.0)
    assert s({"AU12": 0.8}, 0.0) == {"AU12": 0.8}
    later = s({}, 0.1)
    assert 0.0 < later["AU12"] < 0.8
    with pytest.raises(ValueError, match="min_cutoff_hz"):
        AUSmoother(min_cutoff_hz=0.0)


# -- the source on a fake clock --
def _source(clock: FakeClock, **kw: object) -> StreamSource:
    return StreamSource(MessageDecoder("human"), smoothing=None, clock=clock, **kw)  # type: ignore[arg-type]


def test_neutral_before_data_then_latest_value() -> None:
    clock = FakeClock()
    src = _source(clock)
    assert src.sample(0.0).aus == {} and src.stats.dropouts == 0
    assert src.feed('{"t": 1.0, "aus": {"AU12": 0.3}}')
    assert src.feed('{"t": 1.1, "aus": {"AU12": 0.6, "AU1": 0.2}}')
    frame = src.sample(0.02)
    assert frame.t_s == 0.02 and dict(frame.aus) == {"AU12": 0.6, "AU1": 0.2} and frame.face_type == "human"
    assert not src.feed('{"t": 1.05, "aus": {"AU12": 0.9}}')  # older than the newest: out of order
    assert src.stats.out_of_order == 1 and src.sample(0.04).get("AU12") == 0.6


def test_bad_message_is_counted_named_and_never_becomes_the_value() -> None:
    clock = FakeClock()
    src = _source(clock)
    src.feed('{"aus": {"AU12": 0.4}}')
    for bad in (
        '{"aus": {"AU12": 0.5, "AU4": 1.7}}',
        '{"aus": {"AU12": NaN}}',
        "garbage",
        '{"aus": {"AU99": 1}}',
    ):
        assert not src.feed(bad)
    assert src.stats.bad == 4 and src.stats.good == 1 and src.stats.messages == 5
    assert "aus.AU4" in src.stats.errors[0] and "AU99" in src.stats.errors[-1]
    assert dict(src.sample(0.0).aus) == {"AU12": 0.4}  # one bad field rejected the whole message


def test_dropout_eases_to_neutral_and_counts_once() -> None:
    clock = FakeClock()
    src = _source(clock, dropout_ms=200.0, ease_s=0.4)
    src.feed('{"aus": {"AU12": 0.8}}')
    clock.now += 0.19
    assert src.sample(0).get("AU12") == 0.8 and src.stats.dropouts == 0
    clock.now += 0.21  # 0.4 s old: 0.2 s into the 0.4 s ease
    assert src.sample(0).get("AU12") == pytest.approx(0.4)
    clock.now += 0.3
    assert src.sample(0).get("AU12") == 0.0
    assert src.stats.dropouts == 1 and src.stats.samples_in_dropout == 2
    src.feed('{"aus": {"AU12": 0.5}}')  # data again: fresh, then a second dropout later
    assert src.sample(0).get("AU12") == 0.5
    clock.now += 1.0
    src.sample(0)
    assert src.stats.dropouts == 2


def test_dropout_hold_keeps_the_last_aus_and_low_confidence_is_no_data() -> None:
    clock = FakeClock()
    src = _source(clock, dropout="hold", min_confidence=0.5)
    src.feed('{"aus": {"AU2": 0.7}, "confidence": 0.9}')
    assert not src.feed('{"aus": {"AU2": 0.1}, "confidence": 0.2}')
    clock.now += 5.0
    assert src.sample(0).get("AU2") == 0.7 and src.stats.low_confidence == 1 and src.stats.dropouts == 1
    with pytest.raises(InputError, match="dropout"):
        _source(clock, dropout="freeze")


def test_smoothing_in_the_source_follows_with_lag_on_the_clock() -> None:
    clock = FakeClock()
    src = StreamSource(smoothing=AUSmoother(min_cutoff_hz=1.0, beta=0.0), clock=clock)
    src.feed('{"aus": {"AU12": 0.0}}')
    src.sample(0)
    src.feed('{"aus": {"AU12": 1.0}}')
    values = []
    for k in range(1, 6):
        clock.now += 0.02
        values.append(src.sample(k * 0.02).get("AU12"))
    assert 0.0 < values[0] < values[-1] < 1.0


# -- transports on loopback --
def test_addresses_default_to_loopback_and_remote_needs_consent() -> None:
    assert parse_address("9100") == ("127.0.0.1", 9100) and parse_address("127.0.0.1:0") == ("127.0.0.1", 0)
    for bad in ("abc", "127.0.0.1:70000", "host:x"):
        with pytest.raises(InputError, match="address"):
            parse_address(bad)
    check_host("127.0.0.1", False)
    check_host("localhost", False)
    for host in ("0.0.0.0", "192.168.1.20"):
        with pytest.raises(InputError, match="allow_remote"):
            check_host(host, False)
    check_host("0.0.0.0", True)


def test_udp_loopback_counts_a_malformed_datagram_and_keeps_the_last_good() -> None:
    src = StreamSource(smoothing=None)
    with UdpReceiver(src, "127.0.0.1", 0) as rx:
        assert rx.address[0] == "127.0.0.1"
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            datagrams = [
                json.dumps({"t": 0.0, "aus": {"AU12": 0.2}}).encode(),
                json.dumps({"t": 0.1, "blendshapes": {"mouthSmileLeft": 0.5}}).encode(),
                json.dumps({"t": 0.2, "aus": {"AU12": 4.0}}).encode(),  # out of range
                json.dumps({"t": 0.3, "aus": {"AU12": 0.6, "AU6": 0.3}}).encode(),
                b"{broken",
            ]
            for k, d in enumerate(datagrams, start=1):  # one at a time: each is decoded, none superseded
                tx.sendto(d, rx.address)
                assert _wait_for(lambda k=k: src.stats.messages == k)  # type: ignore[misc]
    assert not rx.running
    assert (src.stats.good, src.stats.bad, src.stats.superseded) == (3, 2, 0)
    assert any("aus.AU12" in e for e in src.stats.errors) and any("JSON" in e for e in src.stats.errors)
    assert dict(src.sample(0.0).aus) == {"AU12": 0.6, "AU6": 0.3}


def test_udp_burst_leaves_no_backlog_the_newest_wins() -> None:
    src = StreamSource(smoothing=None, guard=StreamGuard(burst=200))
    with UdpReceiver(src, "127.0.0.1", 0) as rx, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        for k in range(100):
            tx.sendto(json.dumps({"t": k, "aus": {"AU12": k / 100}}).encode(), rx.address)
        assert _wait_for(lambda: src.sample(0.0).get("AU12") == 0.99)
    stats = src.stats
    assert stats.messages <= 100 and stats.good + stats.bad + stats.superseded + stats.out_of_order == stats.messages


def test_tcp_loopback_lines_split_across_packets() -> None:
    src = StreamSource(smoothing=None)
    with TcpReceiver(src, "127.0.0.1", 0) as rx, socket.create_connection(rx.address, timeout=2.0) as conn:
        conn.sendall(b'{"t": 0, "aus": {"AU1": 0.1}}\n{"t": 0.1, "au')
        assert _wait_for(lambda: src.stats.messages == 1)
        conn.sendall(b's": {"AU1": 0.4}}\n')  # the split line completes
        assert _wait_for(lambda: src.stats.messages == 2)
        assert src.sample(0).get("AU1") == 0.4
        conn.sendall(b"not json\n\n")
        assert _wait_for(lambda: src.stats.messages == 3)
        conn.sendall(b'{"t": 0.2, "aus": {"AU1": 0.5}}')  # the last line has no newline: taken at close
        conn.shutdown(socket.SHUT_WR)
        assert _wait_for(lambda: src.stats.messages == 4)
    assert (src.stats.good, src.stats.bad) == (3, 1) and src.sample(0).get("AU1") == 0.5


def test_line_receiver_reads_a_stream_to_its_end() -> None:
    src = StreamSource(smoothing=None)
    text = '{"aus": {"AU4": 0.3}}\n{"aus": {"AU4": -1}}\n{"aus": {"AU4": 0.5}}\n'
    with LineReceiver(src, io.StringIO(text)) as rx:
        assert rx.eof.wait(2.0)
    assert (src.stats.good, src.stats.bad) == (2, 1) and src.sample(0).get("AU4") == 0.5


# -- end to end on the emulator --
@pytest.fixture(scope="module")
def face() -> Iterator[Face]:
    f = Face.open("human", emulate=True, wire_time=False)
    yield f
    f.close(ease_s=0.0)


def _goals_within_limits(face: Face) -> int:
    cal = face.pipeline.calibration
    writes = face.chain.goal_writes()
    for _, sid, tick in writes:
        servo = cal.by_id(sid)
        assert servo.min_tick <= tick <= servo.max_tick, f"servo {sid} goal {tick} outside its limits"
    return len(writes)


def test_udp_stream_end_to_end_on_the_emulator(face: Face) -> None:
    src = StreamSource(MessageDecoder("human"), dropout_ms=300.0)
    before = len(face.chain.goal_writes())
    neutral = dict(face.pipeline.last_goals_tick)
    corner = face.pipeline.calibration["lip_corner_l"].servo_id
    with UdpReceiver(src, "127.0.0.1", 0) as rx, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        stop = threading.Event()

        def send() -> None:
            k = 0
            while not stop.is_set() and k < 40:
                smile = min(1.0, 0.06 * k)  # a human-speed smile: the gate need not clip it
                msg = {
                    "t": k / 30,
                    "blendshapes": {"mouthSmileLeft": smile, "jawOpen": 0.2 * smile},
                    "head": {"yaw_deg": 10.0 * smile},
                }
                tx.sendto(json.dumps(msg).encode(), rx.address)
                if k == 5:
                    tx.sendto(b'{"aus": {"AU12L": "inf"}}', rx.address)
                k += 1
                time.sleep(1 / 30)

        sender = threading.Thread(target=send, daemon=True)
        sender.start()
        perf = follow(face.pipeline, src, 1.0, on_frame=face.traces.append)
        stop.set()
        sender.join(2.0)
    assert perf.traces and src.stats.bad == 1 and src.stats.good > 10
    assert all(0.0 <= v <= 1.0 for t in perf.traces for v in t.aus.values())
    assert max(t.aus.get("AU12L", 0.0) for t in perf.traces) > 0.5
    assert len(face.chain.goal_writes()) > before and _goals_within_limits(face) > 0
    assert face.pipeline.last_goals_tick[corner] != neutral[corner]  # the mouth corner followed the smile


def test_recording_plays_through_play_timeline(face: Face) -> None:
    from servoface.controller.inputs import load_recording

    from tests.controller.test_inputs_files import SAMPLES

    rec = load_recording(SAMPLES / "arkit_smile.jsonl")
    perf = play_timeline(face.pipeline, rec, 0.5, start_s=0.7)
    assert perf.traces[0].t_s == 0.7 and perf.traces[-1].t_s == pytest.approx(1.2)  # late frames are skipped
    assert max(t.aus.get("AU12L", 0.0) for t in perf.traces) > 0.6
    assert _goals_within_limits(face) > 0


# -- CLI --
def test_cli_stream_stdin_summary(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    lines = [json.dumps({"t": k / 30, "aus": {"AU12": 0.05 * k}}) for k in range(10)] + ['{"aus": {"AU12": 9}}']
    monkeypatch.setattr("sys.stdin", io.StringIO("\n".join(lines) + "\n"))
    argv = ["stream", "--emulate", "--stdin", "--arrival", "--duration", "0.4", "--dropout-ms", "100", "--ease", "0.1"]
    rc = cli_main(argv)
    out = capsys.readouterr().out
    assert rc == 0
    assert "messages 11: good 10, bad 1" in out and "dropouts 1" in out and "verdicts" in out
    assert "stdin #11.aus.AU12" in out


@pytest.mark.parametrize(
    "argv,named",
    [
        (["stream", "--emulate", "--udp", "10.1.2.3:9100"], "loopback"),
        (["stream", "--emulate", "--udp", "x:y"], "address"),
        (["stream", "--emulate", "--stdin", "--rate", "0"], "--rate"),
        (["stream", "--emulate", "--stdin", "--duration", "-1"], "--duration"),
        (["stream", "--emulate", "--stdin", "--dropout-ms", "0"], "dropout_ms"),
        (["stream", "--emulate", "--stdin", "--playout-ms", "-5"], "playout_ms"),
        (["stream", "--emulate", "--stdin", "--head", "/nonexistent/head"], "nonexistent"),
    ],
)
def test_cli_stream_bad_args_exit_2(argv: list[str], named: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(argv) == 2
    assert named in capsys.readouterr().err


def test_cli_stream_needs_a_source() -> None:
    with pytest.raises(SystemExit) as info:
        cli_main(["stream", "--emulate"])
    assert info.value.code == 2


def test_cli_play_input_file(capsys: pytest.CaptureFixture[str]) -> None:
    from tests.controller.test_inputs_files import SAMPLES

    assert cli_main(["play", "--emulate", "--input", str(SAMPLES / "greeting.fap")]) == 0
    assert "frames; verdicts" in capsys.readouterr().out
    assert cli_main(["play", "happiness", "--emulate", "--input", str(SAMPLES / "greeting.fap")]) == 2
    assert "one of them" in capsys.readouterr().err
    assert cli_main(["play", "--emulate", "--input", "/nonexistent/rec.csv"]) == 2
    assert "rec.csv" in capsys.readouterr().err


def test_dog_stream_passes_dfacs_through_with_signs() -> None:
    clock = FakeClock()
    src = StreamSource(MessageDecoder("dog"), smoothing=None, clock=clock)
    src.feed('{"aus": {"AU7": -0.5, "AU5L": 0.4}}')
    assert not src.feed('{"blendshapes": {"jawOpen": 0.3}}')
    frame = src.sample(0.0)
    assert frame.face_type == "dog" and dict(frame.aus) == {"AU7": -0.5, "AU5L": 0.4}
    clock.now += 10.0
    assert src.sample(0.0).get("AU7") == 0.0  # eased to neutral (0) from the negative side too


# -- property: whatever arrives, feed() never raises and sample() is a valid frame ------------------------
_json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-10, 10)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=4),
    max_leaves=12,
)
_names = st.sampled_from(["AU12", "AU12L", "AU4", "AU99", "au1", "mouthSmileLeft", "jawOpen", "smile", ""])
_messages = st.fixed_dictionaries(
    {},
    optional={
        "t": _json_values,
        "aus": st.dictionaries(_names, st.floats(-2, 2) | _json_values, max_size=4),
        "blendshapes": st.dictionaries(_names, st.floats(-0.5, 1.5) | _json_values, max_size=4),
        "head": st.dictionaries(st.sampled_from(["yaw_deg", "pitch_deg", "matrix", "x"]), _json_values, max_size=3),
        "confidence": _json_values,
    },
)


@settings(max_examples=150, deadline=None)
@given(st.lists(_messages.map(lambda m: json.dumps(m)) | st.text(max_size=40) | st.binary(max_size=40), max_size=6))
def test_any_input_yields_valid_frames_or_counted_rejects(raw: list[str | bytes]) -> None:
    clock = FakeClock()
    src = StreamSource(MessageDecoder("human", mirror=True), clock=clock)
    for k, item in enumerate(raw):
        src.feed(item)
        clock.now += 0.1
        frame = src.sample(k * 0.1)
        assert all(0.0 <= v <= 1.0 and math.isfinite(v) for v in frame.aus.values())
    assert src.stats.good + src.stats.bad + src.stats.out_of_order == len(raw)


def test_cli_stream_udp_follows_datagrams(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:  # a free loopback port for the CLI
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    stop = threading.Event()

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            for k in range(200):
                if stop.is_set():
                    return
                tx.sendto(
                    json.dumps({"t": k / 50, "blendshapes": {"mouthSmileRight": 0.6}}).encode(),
                    ("127.0.0.1", port),
                )
                time.sleep(0.02)

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    try:
        rc = cli_main(["stream", "--emulate", "--udp", f"127.0.0.1:{port}", "--duration", "0.5", "--mirror"])
    finally:
        stop.set()
        sender.join(2.0)
    out = capsys.readouterr().out
    assert rc == 0 and "bad 0" in out
    good = int(out.split("good ")[1].split(",")[0])
    assert good > 0


def test_face_follow_a_recording_and_rejects_bad_duration(face: Face) -> None:
    from servoface.controller.errors import ControllerError
    from servoface.controller.inputs import load_recording

    from tests.controller.test_inputs_files import SAMPLES

    before = len(face.chain.goal_writes())
    perf = face.follow(load_recording(SAMPLES / "mediapipe_blink.csv"), 0.3)
    assert perf.traces and len(face.chain.goal_writes()) > before and _goals_within_limits(face) > 0
    assert face.pose == dict(perf.traces[-1].aus) and face.pose.get("AU12L", 0.0) > 0.2
    writes = len(face.chain.goal_writes())
    for bad in (-1.0, 0.0, float("nan"), "1"):
        with pytest.raises(ControllerError, match="duration_s"):
            face.follow(load_recording(SAMPLES / "mediapipe_blink.csv"), bad)  # type: ignore[arg-type]
    assert len(face.chain.goal_writes()) == writes


def test_a_restarted_sender_is_followed_not_dropped_as_out_of_order() -> None:
    clock = FakeClock()
    src = _source(clock)
    assert src.feed('{"t": 500.0, "aus": {"AU12": 0.5}}')
    assert not src.feed('{"t": 499.9, "aus": {"AU12": 0.1}}')  # reordering: dropped
    assert src.feed('{"t": 0.0, "aus": {"AU12": 0.2}}')  # the tracker restarted its clock
    assert src.feed('{"t": 0.1, "aus": {"AU12": 0.3}}') and src.sample(0).get("AU12") == 0.3
    clock.now += 1.0  # after a dropout any message is taken, even slightly older
    assert src.feed('{"t": 0.05, "aus": {"AU12": 0.4}}')
    assert (src.stats.out_of_order, src.stats.restarts) == (1, 2)


def test_stream_recorder_writes_a_replayable_jsonl(tmp_path: Path) -> None:
    from servoface.controller.inputs import read_jsonl
    from servoface.controller.inputs.stream import StreamRecorder

    clock = FakeClock()
    recorder = StreamRecorder(tmp_path / "rec.jsonl")
    src = StreamSource(MessageDecoder("human", mirror=True), smoothing=None, clock=clock, on_message=recorder)
    for k in range(5):
        src.feed(json.dumps({"blendshapes": {"mouthSmileLeft": 0.2 * k}, "head": {"yaw_deg": -9.0}}))
        clock.now += 0.04
    src.feed('{"aus": {"AU12": 2}}')  # bad: not recorded
    recorder.close()
    assert recorder.count == 5
    rec = read_jsonl(tmp_path / "rec.jsonl")
    assert rec.duration_s == pytest.approx(0.16) and rec.frames[-1].get("AU12R") == pytest.approx(0.8)
    assert rec.frames[-1].get("AU51") == pytest.approx(0.2)  # mirrored: subject turned right -> robot left
    with pytest.raises(InputError, match="cannot write"):
        StreamRecorder(tmp_path / "no" / "dir" / "rec.jsonl")


def test_playout_interpolates_between_messages_by_arrival() -> None:
    clock = FakeClock()
    src = _source(clock, playout_ms=50.0)
    src.feed('{"aus": {"AU12": 0.0}}')
    clock.now += 0.1
    src.feed('{"aus": {"AU12": 1.0}}')
    assert src.sample(0).get("AU12") == pytest.approx(0.5)  # 50 ms back = halfway between the two
    clock.now += 0.03
    assert src.sample(0).get("AU12") == pytest.approx(0.8)
    clock.now += 0.05
    assert src.sample(0).get("AU12") == 1.0  # past the newest: the newest
    with pytest.raises(InputError, match="playout_ms"):
        _source(clock, playout_ms=-5.0)
