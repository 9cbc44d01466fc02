"""Every way a run ends leaves the head safe — checked from the emulator's side of a real pty.

servoface plays a long script in one process, the emulated human chain runs in another; the test stops
servoface the way a person or a service manager would and then reads the servos' state from the emulator.
"""

from __future__ import annotations

import signal
import sys
import time
from pathlib import Path

import pytest

from tests.integration.safe_stop_rig import LONG_SCRIPT, bench, goals_outside_limits, limits_tick, torque_on_ids

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")


@pytest.mark.parametrize(
    "sig, code, name",
    [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM"), (signal.SIGHUP, 129, "SIGHUP")],
)
def test_one_signal_eases_to_neutral_then_every_torque_off(tmp_path: Path, sig: int, code: int, name: str) -> None:
    with bench(tmp_path) as b:
        b.play(LONG_SCRIPT)
        b.wait_for("# playing")
        time.sleep(1.5)  # mid-performance, servos away from neutral
        b.player.send_signal(sig)  # type: ignore[union-attr]
        status, out, err = b.finish()
        state = b.final_state()
    assert status == code, out + err
    assert f"stop ({name}): eased to neutral" in out and "torque off on every servo" in out, out
    assert torque_on_ids(state) == [], state["servos"]
    assert goals_outside_limits(state) == []
    assert state["torque_writes"] and state["torque_writes"][-1][2] == 0
    neutral = _neutral_ticks()
    last_goal = {int(sid): s["goal_position"] for sid, s in state["servos"].items()}
    assert all(abs(last_goal[sid] - neutral[sid]) <= 2 for sid in neutral), (last_goal, neutral)


def test_second_sigint_hurries_to_neutral_then_every_torque_off(tmp_path: Path) -> None:
    """Ctrl-C twice: no slow easing, but torque is not cut mid-pose either — the head goes to neutral as fast
    as the gate's caps allow, then every servo goes limp."""
    with bench(tmp_path) as b:
        b.play(LONG_SCRIPT)
        b.wait_for("# playing")
        time.sleep(1.5)
        b.player.send_signal(signal.SIGINT)  # type: ignore[union-attr]
        time.sleep(0.05)
        b.player.send_signal(signal.SIGINT)  # type: ignore[union-attr]
        status, out, err = b.finish()
        state = b.final_state()
    assert status == 130, out + err
    assert "stop (SIGINT)" in out and "torque off on every servo" in out, out
    assert "Traceback" not in err
    assert torque_on_ids(state) == []
    assert goals_outside_limits(state) == []
    neutral = _neutral_ticks()
    last_goal = {int(sid): s["goal_position"] for sid, s in state["servos"].items()}
    assert all(abs(last_goal[sid] - neutral[sid]) <= 2 for sid in neutral), (out, last_goal, neutral)


def test_sigint_during_start_up_leaves_every_servo_off(tmp_path: Path) -> None:
    """An empty table cache: start-up builds the gate's tables (seconds); Ctrl-C lands in that build."""
    with bench(tmp_path) as b:
        b.play(LONG_SCRIPT, env={"SERVOFACE_TSS_CACHE": str(tmp_path / "empty-cache")})
        b.wait_for("# opening head")
        time.sleep(0.8)
        b.player.send_signal(signal.SIGINT)  # type: ignore[union-attr]
        status, out, err = b.finish()
        state = b.final_state()
    assert status == 130, out + err
    assert "during start-up" in err and "Traceback" not in err, err
    assert torque_on_ids(state) == []
    assert all(v == 0 for _, _, v in state["torque_writes"])  # torque never went on
    assert state["goal_writes"] == [] or goals_outside_limits(state) == []


def test_a_servo_that_stops_answering_during_the_stop_is_named_and_the_rest_go_off(tmp_path: Path) -> None:
    with bench(tmp_path, "--fault-on-signal", "5:no_reply") as b:
        b.play(LONG_SCRIPT)
        b.wait_for("# playing")
        time.sleep(1.0)
        b.emulator.send_signal(signal.SIGUSR1)  # servo 5 goes silent from now on
        b.emulator_says("fault-on-signal: no_reply on servo 5")  # (not a race: wait until it is so)
        b.player.send_signal(signal.SIGINT)  # type: ignore[union-attr]
        status, out, err = b.finish()
        state = b.final_state()
    assert status == 3, out + err
    assert "NOT REACHED: servo(s) 5" in out and "[5]" in err, out + err
    assert [sid for sid in torque_on_ids(state) if sid != 5] == []  # every other servo: torque off
    assert goals_outside_limits(state) == []


def test_the_chain_vanishing_mid_run_stops_the_run_as_a_bus_failure(tmp_path: Path) -> None:
    """The far end dies (the emulator process killed: the pty closes, as when a USB adapter is pulled):
    servoface stops driving at once, says so and exits non-zero (3: torque-off could not be confirmed)."""
    with bench(tmp_path) as b:
        b.play(LONG_SCRIPT)
        b.wait_for("# playing")
        time.sleep(1.0)
        b.emulator.kill()
        b.emulator.wait(timeout=30)
        status, out, err = b.finish()
    assert status == 3, out + err
    assert "stop (bus failure)" in out and "NOT REACHED" in out, out
    assert "bus failure" in err and "Traceback" not in err, err


def test_sigkill_the_watchdog_stops_every_servo(tmp_path: Path) -> None:
    """The host dies (SIGKILL: no handler runs): the Bus Watchdog, armed while driving, stops the servos.
    Checked the real-servo way: the stock SDK over the pty once servoface is gone."""
    import dynamixel_sdk as sdk

    with bench(tmp_path) as b:
        b.play(LONG_SCRIPT)
        b.wait_for("# playing")
        time.sleep(1.5)
        b.player.send_signal(signal.SIGKILL)  # type: ignore[union-attr]
        b.player.wait(timeout=30)  # type: ignore[union-attr]
        time.sleep(0.5)  # > the 0.1 s default watchdog
        port = sdk.PortHandler(b.port)
        assert port.openPort() and port.setBaudRate(1_000_000)
        packet = sdk.PacketHandler(2.0)
        ids = sorted(limits_tick())
        try:
            first = {i: _read(packet, port, i, 132, 4) for i in ids}
            watchdog = {i: _read(packet, port, i, 98, 1) for i in ids}
            moving = {i: _read(packet, port, i, 122, 1) for i in ids}
            time.sleep(0.5)
            second = {i: _read(packet, port, i, 132, 4) for i in ids}
        finally:
            port.closePort()
        state = b.final_state()
    assert all(v == 0xFF for v in watchdog.values()), watchdog  # tripped (reads -1)
    assert all(v == 0 for v in moving.values()), moving
    assert first == second  # standing still
    trips_after_s = _last_goal_to_end(state)
    assert trips_after_s > 0.5  # no goal reached the servos after the host died


def _read(packet: object, port: object, servo_id: int, address: int, size: int) -> int:
    fn = {1: "read1ByteTxRx", 4: "read4ByteTxRx"}[size]
    for _ in range(5):
        value, comm, err = getattr(packet, fn)(port, servo_id, address)
        if comm == 0:
            return int(value)
    raise AssertionError(f"servo {servo_id} did not answer a read of {address}")


def _last_goal_to_end(state: dict) -> float:  # type: ignore[type-arg]
    last = max(t for t, _, _ in state["goal_writes"])
    return float(state["t_s"]) - last


def _neutral_ticks() -> dict[int, int]:
    from servoface.calibration import load_calibration
    from servoface.sim.heads import load_head

    cal = load_calibration(load_head("human").calibration_path)
    return {s.servo_id: s.neutral_tick for s in cal.servos}
