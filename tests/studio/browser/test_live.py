"""The studio in a real browser (Debian's Chromium through Playwright): what a click does is read from the
emulated servos, the far end of the wire."""

from __future__ import annotations

import time
from typing import Any

from tests.studio.conftest import StudioRig


def _servo_id(rig: StudioRig, role: str) -> int:
    return int(next(s["id"] for s in rig.client.get("/api/head").json()["servos"] if s["role"] == role))


def _present(rig: StudioRig, servo_id: int) -> int:
    return int(rig.chain.servo(servo_id).position_tick)


def test_moving_a_slider_moves_the_emulated_servo(studio_page: tuple[Any, StudioRig]) -> None:
    page, rig = studio_page
    jaw = _servo_id(rig, "jaw")
    rest = _present(rig, jaw)
    lo, hi = rig.limits()[jaw]
    page.locator('input[data-au="AU26"]').fill("0.8")  # Jaw Drop, in the page's jaw group
    rig.wait_for(lambda: abs(_present(rig, jaw) - rest) > 60, timeout_s=60, what="the jaw servo to move")
    rig.wait_for(lambda: not rig.chain.servo(jaw).read_register("Moving"), timeout_s=60, what="the jaw to settle")
    opened = _present(rig, jaw)
    assert lo <= rig.goal_tick(jaw) <= hi
    # the slider back to 0 (double-click) brings the servo back
    page.locator('input[data-au="AU26"]').dblclick()
    rig.wait_for(lambda: abs(_present(rig, jaw) - rest) <= 3, timeout_s=60, what="the jaw back at rest")
    assert abs(opened - rest) > 60
    # a sided AU split into left and right moves only its own side
    lips = page.locator('.region[data-region="lips"]')
    lips.locator('button[data-action="split"]').click()
    left, right = _servo_id(rig, "lip_corner_l"), _servo_id(rig, "lip_corner_r")
    rest_l, rest_r = _present(rig, left), _present(rig, right)
    page.locator('input[data-au="AU12L"]').fill("1")
    rig.wait_for(lambda: abs(_present(rig, left) - rest_l) > 40, timeout_s=60, what="the left lip corner to move")
    assert abs(_present(rig, right) - rest_r) <= 3


def test_the_estop_turns_every_servo_torque_off(studio_page: tuple[Any, StudioRig]) -> None:
    page, rig = studio_page
    rig.wait_for(lambda: all(rig.torque(i) == 1 for i in rig.chain.ids), what="torque on everywhere first")
    page.locator('input[data-au="AU26"]').fill("0.6")  # the head is moving when the button is pressed
    page.click("#estop")
    rig.wait_for(lambda: all(rig.torque(i) == 0 for i in rig.chain.ids), timeout_s=30, what="torque off everywhere")
    page.wait_for_selector("body.latched")
    # the banner is filled by the page's next state update (a frame after the class): wait for it, not race it
    page.wait_for_function("document.querySelector('#banner').innerText.includes('E-stop latched')", timeout=30_000)
    goals = rig.goals()
    # sliders do nothing while latched: the studio refuses, nothing reaches the wire
    page.locator('input[data-au="AU12"]').fill("1")
    page.wait_for_timeout(500)
    assert rig.goals() == goals and all(rig.torque(i) == 0 for i in rig.chain.ids)
    # the banner clears the latch; torque stays off until asked for
    page.click("#banner button")
    page.wait_for_selector("body:not(.latched)")
    page.wait_for_selector("#torque-pill.warn")
    assert all(rig.torque(i) == 0 for i in rig.chain.ids)


def test_the_servos_page_shows_telemetry_and_jogs_within_limits(studio_page: tuple[Any, StudioRig]) -> None:
    page, rig = studio_page
    jaw = _servo_id(rig, "jaw")
    page.click('a[data-page="servos"]')
    row = page.locator(f'tr[data-servo="{jaw}"]')
    page.wait_for_function(f"document.querySelector('tr[data-servo=\"{jaw}\"] td:nth-child(5)').textContent !== '–'")
    assert row.locator("td").nth(4).inner_text().strip() == str(_present(rig, jaw))
    page.check("#manual")
    page.wait_for_selector("#page-servos.manual")
    start = rig.goal_tick(jaw)
    page.select_option("#jog-step", "50")
    row.locator('button[data-action="jog+"]').click()
    rig.wait_for(lambda: rig.goal_tick(jaw) == start + 50, timeout_s=30, what="the jog on the wire")
    page.uncheck("#manual")
    page.wait_for_selector("#page-servos:not(.manual)")


def test_a_state_older_than_the_click_does_not_flip_the_manual_box_back(studio_page: tuple[Any, StudioRig]) -> None:
    """The page's first GET of the state (or a push) can arrive after the user's click on "manual": the box
    keeps what was clicked until the server answers, then shows the answer (it once flipped back, and a
    loaded CI machine caught it)."""
    page, rig = studio_page
    page.click('a[data-page="servos"]')
    held: list[Any] = []
    page.route("**/api/servos/manual", lambda route: held.append(route))  # it waits here until continued
    page.check("#manual")
    deadline = time.monotonic() + 30
    while not held and time.monotonic() < deadline:
        page.wait_for_timeout(20)
    assert held, "the page sent no manual-mode request"
    stale = "() => { const s = {...window.studio.state, manual: false}; window.studio.listeners.forEach((f) => f(s)); }"
    page.evaluate(stale)  # a state that left the server before the click
    assert page.is_checked("#manual")
    assert rig.client.get("/api/state").json()["manual"] is False  # (the request is still held)
    held[0].continue_()
    page.wait_for_selector("#page-servos.manual")
    assert page.is_checked("#manual") and rig.client.get("/api/state").json()["manual"] is True
    page.unroute("**/api/servos/manual")
    page.uncheck("#manual")
    page.wait_for_selector("#page-servos:not(.manual)")
    assert rig.client.get("/api/state").json()["manual"] is False


def test_closing_the_tab_eases_the_head_to_neutral_unless_hold(browser: Any, studio: StudioRig) -> None:
    from tests.studio.browser.conftest import open_page

    rig = studio
    jaw = _servo_id(rig, "jaw")
    rest = _present(rig, jaw)
    for hold in (True, False):
        page = open_page(browser, rig)
        if hold:
            page.check("#hold")
            rig.wait_for(lambda: rig.client.get("/api/state").json()["hold"], what="hold on")
        page.locator('input[data-au="AU26"]').fill("0.8")
        rig.wait_for(lambda: abs(_present(rig, jaw) - rest) > 60, timeout_s=60, what="the jaw to open")
        page.context.close()  # the tab is gone: its WebSocket closes
        rig.wait_for(lambda: rig.client.get("/api/state").json()["clients"] == 0, what="the socket to close")
        if hold:
            rig.wait_for(lambda: rig.service.status().tracks["studio"].state == "holding", what="the pose held")
            time.sleep(2.0)  # more than the 1 s in which a drop without hold eases to neutral
            assert abs(_present(rig, jaw) - rest) > 60  # held: still open
            rig.client.post("/api/hold", json={"hold": False}).raise_for_status()
            rig.client.post("/api/neutral", json={"transition_s": 0.2}).raise_for_status()
        rig.wait_for(lambda: abs(_present(rig, jaw) - rest) <= 3, timeout_s=60, what="the jaw back at neutral")


def test_a_page_that_goes_silent_eases_the_head_to_neutral_with_its_socket_open(
    studio_page: tuple[Any, StudioRig],
) -> None:
    """The page's heartbeat: its JavaScript frozen (the debugger pauses it; a dead network looks the same to
    the server) while Chromium keeps the WebSocket open -> silence -> neutral; resumed, nothing moves."""
    page, rig = studio_page
    jaw = _servo_id(rig, "jaw")
    rest = _present(rig, jaw)
    page.locator('input[data-au="AU26"]').fill("0.8")
    rig.wait_for(lambda: abs(_present(rig, jaw) - rest) > 60, timeout_s=60, what="the jaw to open")
    cdp = page.context.new_cdp_session(page)
    cdp.send("Debugger.enable")
    cdp.send("Debugger.pause")
    rig.wait_for(lambda: abs(_present(rig, jaw) - rest) <= 3, timeout_s=60, what="the jaw back at neutral")
    state = rig.client.get("/api/state").json()
    assert state["clients"] == 1 and state["last_drop_reason"] == "silent"  # the socket is still open
    cdp.send("Debugger.resume")
    rig.wait_for(lambda: rig.client.get("/api/state").json()["silent_clients"] == 0, what="the page live again")
    assert abs(_present(rig, jaw) - rest) <= 3  # back, but nothing moves until the user acts
    cdp.detach()
