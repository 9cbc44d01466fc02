"""Pausing lends the bus to the caller; on resume the service starts from what is on the wire (no jump)."""

from __future__ import annotations

from servoface.controller.pipeline import Pipeline
from servoface.controller.service import Status

from tests.controller.service.conftest import Running


def test_resume_after_another_pipeline_moved_the_servos_does_not_jump(running: Running) -> None:
    svc, chain = running.service, running.chain
    assert svc.set_aus({"AU12": 0.5}, track="face", transition_s=0.2).wait(5.0) is Status.DONE
    with svc.paused_loop():
        n_paused = len(chain.goal_writes())
        other = Pipeline(running.head, running.pipeline.calibration, driver=running.pipeline.driver)
        other.pin_to(running.pipeline.last_goals_tick)
        for _ in range(40):  # a second pipeline walks the brows up while the service waits
            other.step({"AU1": 1.0, "AU2": 1.0})
        moved = dict(other.last_goals_tick)
        assert len(chain.goal_writes()) == n_paused + 40 * len(chain.ids)  # only ours went out
    first = svc.wait_frame(svc.last_trace.index)
    assert first is not None
    cap = running.pipeline.gate.table.max_step_tick
    index = running.pipeline.gate.table.index()
    for sid, tick in first.goals_sent.items():  # the first frame after resume steps from the wire's goals
        assert abs(tick - moved[sid]) <= int(cap[index[sid]]), sid
    assert svc.wait_settled(timeout_s=5.0)
