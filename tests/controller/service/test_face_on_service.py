"""`Face` is a blocking client of its head service: another front end may drive the same head meanwhile."""

from __future__ import annotations

import threading

import pytest
from servoface.controller.face import Face
from servoface.controller.service import Status


def test_a_face_call_and_a_gaze_from_another_thread_share_the_head() -> None:
    face = Face.open("human", emulate=True, wire_time=False)
    try:
        svc = face.service
        looked: list[Status] = []
        other = threading.Thread(target=lambda: looked.append(svc.look_at((250.0, 0.0, 600.0)).wait(5.0)))
        other.start()
        perf = face.express("happiness", transition_s=0.3, hold_s=0.6)
        other.join()
        assert looked == [Status.DONE]
        last = perf.traces[-1]
        assert last.aus["AU12"] > 0.5 and last.aus.get("AU61", 0.0) > 0.0  # both on the wire's frame
        assert "AU61" not in face.pose and face.pose["AU12"] == pytest.approx(last.aus["AU12"])  # Face's own track
        assert perf.traces[0].t_s >= 0.0 and perf.traces[-1].t_s >= 0.9 - 1e-6  # timed from the call's start
    finally:
        face.close()
    assert all(not face.chain.servo(s).torque_on for s in face.chain.ids)
