"""The README's stop table, the rows that had no end-to-end test: an exception mid-run, and servos latched or
missing at the end. `servoface play --emulate` runs in process (its `main`), the emulated chain is taken from
the emulator's side (`ServoChain.create` is wrapped only to hand the test the chain it made), the trouble is
made once the head is driving (torque on everywhere), and the test checks every servo's own torque state, the
exit status and the closing summary."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from servoface.controller.cli import main
from servoface.controller.pipeline import Pipeline
from servoface.hardware.emulator import ServoChain


@pytest.fixture
def chains(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[Any]]:
    """Every chain `Face.open(emulate=True)` creates during the test (the real class, only recorded)."""
    made: list[Any] = []
    real = ServoChain.create.__func__  # type: ignore[attr-defined]

    def create(cls: type, *args: Any, **kw: Any) -> Any:
        chain = real(cls, *args, **kw)
        made.append(chain)
        return chain

    monkeypatch.setattr(ServoChain, "create", classmethod(create))
    yield made


def _driving(chains: list[Any]) -> bool:
    if not chains:
        return False
    chain = chains[-1]
    return all(chain.servo(s).torque_on for s in chain.ids)


def _when_driving(chains: list[Any], then: Callable[[Any], None], timeout_s: float = 120.0) -> threading.Thread:
    """Once every servo has torque on (the run is driving), wait 0.3 s more (mid-motion) and call ``then``."""

    def watch() -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not _driving(chains):
            time.sleep(0.01)
        time.sleep(0.3)
        if chains:
            then(chains[-1])

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def test_an_exception_mid_run_ends_in_the_stop_path(
    chains: list[Any], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bug in a frame (here: `Pipeline.step` raising once, mid-motion): the service's loop ends, the stop
    path turns torque off on every servo, the command says so and exits 1."""
    armed = threading.Event()
    real_step = Pipeline.step

    def step(self: Pipeline, *args: Any, **kw: Any) -> Any:
        if armed.is_set():
            armed.clear()
            raise RuntimeError("injected bug in a frame")
        return real_step(self, *args, **kw)

    monkeypatch.setattr(Pipeline, "step", step)
    watcher = _when_driving(chains, lambda chain: armed.set())
    status = main(["play", "surprise", "--emulate", "--hold", "20"])
    watcher.join(5.0)
    out, err = capsys.readouterr()
    chain = chains[-1]
    assert not armed.is_set(), "the bug never fired"
    assert all(not chain.servo(s).torque_on for s in chain.ids), "a servo kept torque on"
    assert status == 1, (status, out, err)
    assert "RuntimeError" in err and "injected bug" in err, err
    assert "stop (error" in out and "torque off on every servo" in out, out
    assert "Traceback" not in err


def test_a_servo_latched_at_the_end_is_named_and_the_run_exits_1(
    chains: list[Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Mid-run, servo 7 reports an electrical-shock fault (latched off: it needs a human). The run plays to
    its end; the rest ease to neutral and turn torque off; the summary names 7 as latched; exit 1."""
    watcher = _when_driving(chains, lambda chain: chain.faults.inject(7, "electrical_shock"))
    status = main(["play", "surprise", "--emulate", "--hold", "2"])
    watcher.join(5.0)
    out, err = capsys.readouterr()
    chain = chains[-1]
    assert all(not chain.servo(s).torque_on for s in chain.ids), "a servo kept torque on"
    assert "stop (end): eased to neutral" in out and "torque off on every servo" in out, out
    assert "latched: servo(s) 7" in out, out
    assert status == 1, (status, out, err)
    assert "Traceback" not in err


def test_a_servo_gone_at_the_end_is_named_not_reached_and_the_run_exits_3(
    chains: list[Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Mid-run, servo 9's bus wiring is cut (silent from then on) and servo 7 latches: the rest ease to
    neutral and turn torque off; the summary names 9 as not reached (its torque-off cannot be confirmed: it
    is missing at the end) and 7 as latched; exit 3, the warning on stderr too."""

    def break_two(chain: Any) -> None:
        chain.faults.inject(7, "electrical_shock")
        chain.faults.inject(9, "disconnect")

    watcher = _when_driving(chains, break_two)
    status = main(["play", "surprise", "--emulate", "--hold", "2"])
    watcher.join(5.0)
    out, err = capsys.readouterr()
    chain = chains[-1]
    assert all(not chain.servo(s).torque_on for s in chain.ids if s != 9), "a reachable servo kept torque on"
    assert "NOT REACHED: servo(s) 9" in out and "latched: servo(s) 7" in out, out
    assert "torque-off NOT confirmed on servo(s) [9]" in err, err
    assert status == 3, (status, out, err)
    assert "Traceback" not in err


def test_a_servo_missing_at_the_end_whose_torque_off_is_confirmed_is_named_missing_and_the_run_exits_1(
    chains: list[Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """Mid-run, servo 9 stops answering (a loose data wire: it still hears every packet, its replies are lost):
    the driver takes it out of service (`MISSING`, re-probed). Its replies come back just as the stop's
    broadcast Torque Enable = 0 goes out — after the last re-probe, so the driver still has it missing — and
    it acknowledges its own torque-off. The README's row: the rest eased and off; the summary names 9 as
    missing, not as NOT REACHED (its torque-off is confirmed); every servo off on the emulator, the Bus
    Watchdog disarmed on all of them; exit 1."""
    from servoface.hardware.emulator.packet import Instruction
    from servoface.hardware.emulator.packet_log import register_writes

    silent_since: list[float] = []
    answers_again: list[float] = []

    def lose_replies(chain: Any) -> None:
        log = chain.log
        real_append = log.append

        def append(entry: Any) -> None:  # the far end of the wire sees the stop's broadcast torque-off
            real_append(entry)
            if not answers_again and entry.id == 254 and entry.instruction == Instruction.SYNC_WRITE:
                if any(sid == 9 and v == 0 for _, sid, v in register_writes([entry], 64, 1)):
                    answers_again.append(entry.t_s)
                    chain.faults.clear(9, "no_reply")

        log.append = append
        silent_since.append(chain.time_s)
        chain.faults.inject(9, "no_reply")

    watcher = _when_driving(chains, lose_replies)
    status = main(["play", "surprise", "--emulate", "--hold", "2"])
    watcher.join(5.0)
    out, err = capsys.readouterr()
    chain = chains[-1]
    assert silent_since and answers_again, "the fault never started or the stop's torque-off never came"
    assert all(not chain.servo(s).torque_on for s in chain.ids), "a servo kept torque on"
    assert all(chain.servo(s).read_register("Bus Watchdog") == 0 for s in chain.ids), "a watchdog left armed"
    assert "stop (end): eased to neutral" in out and "torque off on every servo" in out, out
    assert "missing: servo(s) 9" in out and "NOT REACHED" not in out + err, out + err
    assert "torque off confirmed" in out, out  # it did answer at the stop: the line must not say it did not
    assert status == 1, (status, out, err)
    assert "Traceback" not in err
