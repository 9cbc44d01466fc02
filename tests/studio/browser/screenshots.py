"""Take the README's screenshots of the studio (docs/studio/*.png) in Debian's Chromium, on the emulated
human head with the twin rendering: ``python -m tests.studio.browser.screenshots [OUT_DIR]``."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from servoface.controller.service import HeadService, open_head
from servoface.controller.studio import StudioOptions, StudioServer

from tests.studio.browser.conftest import TIMEOUT_MS, chromium_path

DOCUMENT = {
    "script": {"face": "human", "title": "Greeting", "end_s": 4.0},
    "expressions": {
        "face_keys": {
            "keyframes": [
                {"t_s": 0.0, "pose": {}, "easing": "linear"},
                {"t_s": 0.8, "pose": {"AU1": 0.6, "AU2": 0.6, "AU5": 0.4}, "easing": "min_jerk"},
                {"t_s": 1.6, "pose": {"AU6": 0.6, "AU12": 0.9, "AU25": 0.3}, "easing": "min_jerk"},
                {"t_s": 2.6, "pose": {"AU6": 0.5, "AU12": 0.7, "AU14L": 0.3}, "easing": "ease_in_out"},
                {"t_s": 3.6, "pose": {}, "easing": "min_jerk"},
            ]
        }
    },
    "play": [
        {"at_s": 0.0, "expression": "face_keys"},
        {"at_s": 1.2, "track": "gesture", "library": "brow_flash"},
        {"at_s": 2.0, "track": "speech", "say": "Hello, nice to meet you."},
    ],
    "gaze": [
        {"at_s": 0.4, "look_at_mm": [150.0, 40.0, 600.0]},
        {"at_s": 2.2, "look_at_mm": [-120.0, -20.0, 600.0]},
        {"at_s": 3.4, "ahead": True},
    ],
    "blink": {"enabled": True, "seed": 1},
}


def main(out_dir: Path) -> None:
    from playwright.sync_api import sync_playwright

    path = chromium_path()
    if path is None:
        raise SystemExit("no Chromium: sudo apt-get install chromium")
    out_dir.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="studio-shots-"))
    opened = open_head("human", emulate=True)
    service = HeadService(opened.head, opened.pipeline)
    server = StudioServer(service, port=0, options=StudioOptions(out_dir=work, scripts_dir=work)).start()
    try:
        import httpx

        api = httpx.Client(base_url=server.base_url, headers={"Authorization": f"Bearer {server.token}"}, timeout=60)
        api.put("/api/scripts/greeting.toml", json={"document": DOCUMENT}).raise_for_status()
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=path, args=["--no-sandbox", "--disable-gpu"])
            page = browser.new_page(viewport={"width": 1440, "height": 900}, device_scale_factor=1)
            page.set_default_timeout(TIMEOUT_MS)
            page.goto(f"{server.url}#live")
            page.wait_for_function("document.body.dataset.ready === '1'")
            page.wait_for_selector("#conn.ok")
            for au, value in (("AU1", "0.5"), ("AU2", "0.4"), ("AU6", "0.6"), ("AU12", "0.85"), ("AU26", "0.35")):
                page.locator(f'#page-live input[data-au="{au}"]').fill(value)
                time.sleep(0.15)
            page.check("#show-target")
            page.evaluate("window.scrollTo(0, 0)")
            page.wait_for_function("document.querySelector('img[data-which=target]').dataset.seq")
            time.sleep(3.0)
            page.screenshot(path=str(out_dir / "live.png"))

            opened.chain.faults.inject_now(10, "overheating", duration_s=4.0)  # a fault to show in the table
            page.click('a[data-page="servos"]')
            time.sleep(3.0)
            page.screenshot(path=str(out_dir / "servos.png"))

            page.click('a[data-page="live"]')
            page.click("#neutral")
            time.sleep(1.5)
            page.click('a[data-page="calibrate"]')
            page.check('input[data-role="jaw"]')
            page.fill("#cal-points", "2")
            page.click("#cal-start")
            page.wait_for_selector('.calibrate[data-step="neutral"]')
            time.sleep(1.0)
            page.click("#cal-capture")
            page.wait_for_selector('.calibrate[data-step="upper"]')
            page.fill("#cal-step", "150")
            page.click("#cal-jog-up")
            time.sleep(1.5)
            page.click("#cal-suggested")
            time.sleep(1.5)
            page.click("#cal-capture")
            page.wait_for_selector('.calibrate[data-step="point"]')
            page.click("#cal-suggested")
            time.sleep(2.0)
            page.wait_for_function("document.querySelector('#cal-twin').complete")
            time.sleep(1.0)
            page.screenshot(path=str(out_dir / "calibrate.png"))
            page.click("#cal-abort")

            page.click('a[data-page="author"]')
            page.select_option("#author-list", "greeting.toml")
            page.wait_for_selector('.tl-row[data-row="keys:face"] .tl-key')
            page.locator('.tl-row[data-row="keys:face"] .tl-key').nth(2).click()
            page.wait_for_function("document.querySelector('#author-twin').dataset.t === '1.6'")
            time.sleep(1.5)
            page.screenshot(path=str(out_dir / "author.png"))
            browser.close()
    finally:
        server.stop()
        service.shutdown(ease_s=0.0)
        opened.chain.close()


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/studio"))
