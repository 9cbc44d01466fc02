"""Author a two-keyframe timeline in the browser, save it, and `servoface play` the saved file on a separate
emulator: the goals on that wire are the ones the studio's head takes for the same timeline."""

from __future__ import annotations

import io
import tomllib
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from servoface.controller.script import load_script

from tests.integration.safe_stop_rig import bench
from tests.studio.conftest import StudioRig


def _set(page: Any, selector: str, value: str) -> None:
    page.fill(selector, value)
    page.dispatch_event(selector, "change")


def _plateau(writes: list[list[float]]) -> dict[int, int]:
    """Per servo, the goal written most often: the hold of the last keyframe (1 s of 50 Hz frames)."""
    per: dict[int, Counter[int]] = {}
    for _, sid, tick in writes:
        per.setdefault(int(sid), Counter())[int(tick)] += 1
    return {sid: c.most_common(1)[0][0] for sid, c in per.items()}


def test_a_two_keyframe_timeline_saved_in_the_page_plays_the_same_goals_with_servoface_play(
    studio_page: tuple[Any, StudioRig], tmp_path: Path
) -> None:
    page, rig = studio_page
    page.click('a[data-page="author"]')
    page.click("#author-add-key")  # key 1 at the playhead, 0 s: neutral
    page.wait_for_selector(".tl-key.selected")
    page.click("#author-add-key")  # the same time again selects it instead of doubling it
    assert page.locator('.tl-row[data-row="keys:face"] .tl-key').count() == 1
    # key 2: double-click the face row at ~1 s, then set its time, easing and pose in the inspector
    row = page.locator('.tl-row[data-row="keys:face"]')
    box = row.bounding_box()
    page.mouse.dblclick(box["x"] + 160 * 1.0, box["y"] + box["height"] / 2)
    page.wait_for_function("document.querySelectorAll('.tl-row[data-row=\"keys:face\"] .tl-key').length === 2")
    _set(page, "#key-time", "1")
    page.select_option("#key-easing", "min_jerk")
    page.locator('.inspector input[data-au="AU12"]').fill("0.7")
    page.locator('.inspector input[data-au="AU26"]').fill("0.5")
    _set(page, "#author-end", "2")
    page.fill("#author-name", "two_keys.toml")
    page.click("#author-save")
    page.wait_for_function("document.querySelector('#author-status').dataset.saved")
    saved = Path(page.locator("#author-status").get_attribute("data-saved"))
    assert saved.name == "two_keys.toml" and saved.is_file()

    doc = tomllib.loads(saved.read_text())
    (name,) = doc["expressions"]
    keys = doc["expressions"][name]["keyframes"]
    assert [k["t_s"] for k in keys] == [0.0, 1.0]
    assert keys[0]["pose"] == {} and keys[1]["pose"] == {"AU12": 0.7, "AU26": 0.5}
    assert keys[1]["easing"] == "min_jerk" and doc["script"]["end_s"] == 2.0
    assert doc["play"] == [{"at_s": 0.0, "expression": name}]
    assert load_script(saved).end_s == 2.0  # what servoface play reads

    # the page plays it on the studio's head; it ends holding the last key
    rest = rig.goals()
    page.select_option("#author-on", "head")
    page.click("#author-play")
    rig.wait_for(lambda: rig.service.status().tracks["face"].state == "holding", timeout_s=60, what="the hold")
    rig.wait_for(lambda: not any(rig.chain.servo(i).read_register("Moving") for i in rig.chain.ids), timeout_s=60,
                 what="the servos to settle")  # fmt: skip
    studio_hold = rig.goals()

    # the saved file with `servoface play` on a separate emulator over a pty
    with bench(tmp_path) as b:
        b.play(str(saved), "--head", "human")
        code, out, err = b.finish(timeout_s=240)
        assert code == 0, err
        state = b.final_state()
    cli_hold = _plateau(state["goal_writes"])
    moved = {sid for sid, tick in studio_hold.items() if abs(tick - rest[sid]) > 20}
    assert moved, "the last key moves some servos"
    assert {sid: cli_hold[sid] for sid in studio_hold} == studio_hold


def test_a_script_loaded_and_saved_in_the_page_is_the_same_document(studio_page: tuple[Any, StudioRig]) -> None:
    from tests.studio.browser.screenshots import DOCUMENT

    page, rig = studio_page
    rig.client.put("/api/scripts/greeting.toml", json={"document": DOCUMENT}).raise_for_status()
    page.click('a[data-page="author"]')
    for name in ("human_performance", "greeting.toml"):
        page.wait_for_selector(f'#author-list option[value="{name}"]', state="attached")
        page.select_option("#author-list", name)
        page.wait_for_function(f"document.querySelector('#author-status').textContent.startsWith('Loaded {name}')")
        copy_name = f"copy_of_{name.removesuffix('.toml')}.toml"
        page.fill("#author-name", copy_name)
        page.click("#author-save")
        page.wait_for_function(
            f"(document.querySelector('#author-status').dataset.saved || '').endsWith('{copy_name}')"
        )
        original = rig.client.get(f"/api/scripts/{name.removesuffix('.toml')}.toml").json()["document"]
        copy = rig.client.get(f"/api/scripts/{copy_name}").json()["document"]
        assert copy == original, name
    # the loaded timeline shows its keys, gaze, clip and blinks
    assert page.locator('.tl-row[data-row="keys:face"] .tl-key').count() == 5
    assert page.locator('.tl-row[data-row="gaze"] .tl-key').count() == 3
    assert page.locator('.tl-row[data-row="clips:gesture"] .tl-clip').inner_text() == "brow_flash"
    assert page.is_checked("#author-blink")


def test_a_live_udp_stream_recorded_in_the_page_becomes_face_keys(studio_page: tuple[Any, StudioRig]) -> None:
    """Record → a tracker's AU frames over real UDP → Stop: the keys land on the face track and save."""
    import json
    import socket
    import time

    from tests.studio.test_record import RATE_HZ, _aus

    page, rig = studio_page
    page.click('a[data-page="author"]')
    page.select_option("#author-rec-source", "udp")
    page.fill("#author-rec-port", "0")
    page.click("#author-record")
    page.wait_for_function("document.querySelector('#author-record').dataset.port")
    port = int(page.locator("#author-record").get_attribute("data-port"))
    recording = rig.server.studio.recording
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    n = 45
    try:
        for i in range(n):
            t = i / RATE_HZ
            sender.sendto(json.dumps({"t": t, "aus": _aus(t)}).encode(), ("127.0.0.1", port))
            rig.wait_for(lambda i=i: len(recording.samples) > i, what=f"sample {i} recorded")
            time.sleep(1.0 / RATE_HZ)  # a tracker's pace (the input limits a client to 240 messages/s)
    finally:
        sender.close()
    page.click("#author-record")  # stop
    page.wait_for_function("document.querySelector('#author-status').dataset.recorded")
    count = int(page.locator("#author-status").get_attribute("data-recorded"))
    assert 3 <= count < n
    assert page.locator('.tl-row[data-row="keys:face"] .tl-key').count() == count
    page.fill("#author-name", "recorded.toml")
    page.click("#author-save")
    page.wait_for_function("(document.querySelector('#author-status').dataset.saved || '').endsWith('recorded.toml')")
    doc = tomllib.loads(Path(page.locator("#author-status").get_attribute("data-saved")).read_text())
    (keys,) = [e["keyframes"] for e in doc["expressions"].values()]
    assert len(keys) == count and keys[0]["t_s"] == 0.0
    for key in keys:
        for name, value in _aus(key["t_s"]).items():
            assert abs(key["pose"].get(name, 0.0) - value) <= 0.011, (key, name)


def test_a_speech_cue_made_in_the_page_saves_reloads_and_talks_on_the_head(studio_page: tuple[Any, StudioRig]) -> None:
    """The speech lane: a key with words, saved as `[[play]] say = ...` (the script format), loaded back
    the same, and played on the head: the emulated jaw servo talks (visemes), then rests."""
    page, rig = studio_page
    words = "Hello, nice to meet you."
    page.click('a[data-page="author"]')
    page.click("#author-add-say")
    page.wait_for_selector("#say-text")
    _set(page, "#say-text", words)
    _set(page, "#key-time", "0.2")
    assert page.locator('.tl-row[data-row="clips:speech"] .tl-clip').inner_text() == f"“{words}”"
    page.fill("#author-name", "talk.toml")
    page.click("#author-save")
    page.wait_for_function("(document.querySelector('#author-status').dataset.saved || '').endsWith('talk.toml')")
    doc = tomllib.loads(Path(page.locator("#author-status").get_attribute("data-saved")).read_text())
    assert doc["play"] == [{"at_s": 0.2, "track": "speech", "say": words}]
    # the visemes: the jaw opens and closes while it talks (the script format's own sampling)
    frames = rig.client.post("/api/scripts/sample", json={"document": doc, "fps": 50}).json()["frames"]
    jaw = [f["aus"].get("AU26", 0.0) for f in frames]
    assert jaw[0] == 0.0 and max(jaw) > 0.3
    # loaded back into the page and saved again: the same document
    page.wait_for_selector('#author-list option[value="talk.toml"]', state="attached")
    page.select_option("#author-list", "talk.toml")
    page.wait_for_function("document.querySelector('#author-status').textContent.startsWith('Loaded talk.toml')")
    assert page.locator('.tl-row[data-row="clips:speech"] .tl-clip').inner_text() == f"“{words}”"
    page.fill("#author-name", "talk_again.toml")
    page.click("#author-save")
    page.wait_for_function("(document.querySelector('#author-status').dataset.saved || '').endsWith('talk_again.toml')")
    again = rig.client.get("/api/scripts/talk_again.toml").json()["document"]
    assert again == rig.client.get("/api/scripts/talk.toml").json()["document"]
    # on the head: the jaw servo's goal on the emulator's wire opens, then it is back at rest
    jaw_id = next(a.servo.id for a in rig.service.head.actuators if a.role == "jaw")
    rest = rig.goal_tick(jaw_id)
    writes_before = len(rig.chain.goal_writes())
    page.select_option("#author-on", "head")
    page.click("#author-play")
    rig.wait_for(lambda: abs(rig.goal_tick(jaw_id) - rest) > 30, timeout_s=60, what="the jaw talking")
    rig.wait_for(lambda: rig.goal_tick(jaw_id) == rest, timeout_s=60, what="the jaw at rest after the words")
    moves = {t for _, sid, t in rig.chain.goal_writes()[writes_before:] if sid == jaw_id}
    assert len(moves) > 5  # it opened and closed along the words, not one jump


def test_a_name_with_a_path_is_refused_by_name_in_the_page(studio_page: tuple[Any, StudioRig]) -> None:
    """'../evil name.toml' in the name field: the page shows the server's 422 about file names once (it showed
    "Not Found"; a field-prefixed message was prefixed twice), and nothing is written."""
    page, rig = studio_page
    page.click('a[data-page="author"]')
    page.fill("#author-name", "../evil name.toml")
    page.click("#author-save")
    page.wait_for_function("document.querySelector('#author-status').textContent.includes('bare file name')")
    text = page.inner_text("#author-status")
    assert text.startswith("name: expected a bare file name") and "name: name:" not in text, text
    assert "evil name.toml" not in rig.client.get("/api/scripts").json()["scripts"]


# the box of the first text in an element, from its text node (not the element: a label may be a part of it)
_TEXT_BOX = """(sel) => {
  const el = document.querySelector(sel);
  const keep = (n) => (n.textContent.trim() ? NodeFilter.FILTER_ACCEPT : NodeFilter.FILTER_SKIP);
  const walker = document.createTreeWalker(el, NodeFilter.SHOW_TEXT, { acceptNode: keep });
  const node = walker.nextNode();
  const range = document.createRange();
  range.selectNodeContents(node);
  const r = range.getBoundingClientRect();
  return { x: r.x, y: r.y, w: r.width, h: r.height, text: node.textContent };
}"""
_PLAYHEAD_X = (
    "(() => { const r = document.querySelector('.tl-playhead').getBoundingClientRect(); return r.x + r.width / 2; })()"
)


def test_the_playhead_passes_under_the_timeline_labels(studio_page: tuple[Any, StudioRig]) -> None:
    """A clip's label ("blink") and the blink row's text stay readable where the playhead crosses them: the
    text is drawn over the line (hit testing follows paint order, so the playhead, made hit-testable for
    the check, is not what is found at the text) and no pixel of the line shows inside the text's box."""
    page, _ = studio_page
    page.click('a[data-page="author"]')
    page.wait_for_selector("#author-lib")
    page.select_option("#author-lib", "blink")
    page.click("#author-add-clip")
    page.wait_for_selector('.tl-row[data-row="clips:gesture"] .tl-clip')
    page.add_style_tag(content=".tl-playhead { pointer-events: auto !important; }")
    page.locator(".timeline").scroll_into_view_if_needed()  # points below the window hit nothing
    ruler = page.locator(".tl-ruler").bounding_box()
    for label in ('.tl-row[data-row="clips:gesture"] .tl-clip', '.tl-row[data-row="blink"]'):
        box = page.evaluate(_TEXT_BOX, label)
        assert box["w"] > 10, box
        cx, cy = box["x"] + box["w"] / 2, box["y"] + box["h"] / 2
        page.mouse.click(cx, ruler["y"] + ruler["height"] / 2)  # scrub: the playhead to the text's middle
        page.wait_for_function(f"Math.abs({_PLAYHEAD_X} - {cx}) < 2")
        on_top = page.evaluate(
            "([sel, x, y]) => { const el = document.elementFromPoint(x, y); "
            "return { inside: document.querySelector(sel).contains(el), cls: el ? el.className || el.tagName : '' }; }",
            [label, page.evaluate(_PLAYHEAD_X), cy],
        )
        assert on_top["inside"], f"the playhead is drawn over {box['text']!r} (found {on_top['cls']!r} there)"
        shot = page.screenshot(clip={"x": box["x"], "y": box["y"], "width": box["w"], "height": box["h"]})
        with Image.open(io.BytesIO(shot)) as im:
            rgb = np.asarray(im.convert("RGB")).astype(int)
        red = (rgb[..., 0] > 200) & (rgb[..., 1] < 170) & (rgb[..., 2] < 170)  # the playhead's #ff7b72
        assert not red.any(), f"{int(red.sum())} playhead pixels inside the label {box['text']!r}"
