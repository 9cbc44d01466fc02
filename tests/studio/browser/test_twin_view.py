"""The live twin as the page shows it (Debian's Chromium, the twin rendering on EGL): the whole head is in
the picture, read from a screenshot of the displayed image."""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from PIL import Image

from tests.studio.browser.conftest import open_page
from tests.studio.conftest import StudioRig

TWIN = "#page-live img[data-which=achievable]"


@pytest.fixture
def render_page(browser: Any, studio_render: StudioRig) -> Iterator[tuple[Any, StudioRig]]:
    page = open_page(browser, studio_render)
    yield page, studio_render
    assert not page.errors, f"the page raised: {page.errors}"
    page.context.close()


def test_the_live_twin_shows_the_whole_head(render_page: tuple[Any, StudioRig]) -> None:
    page, _ = render_page
    page.wait_for_function(
        f"(() => {{ const i = document.querySelector('{TWIN}'); "
        "return !!i && !!i.dataset.seq && i.complete && i.naturalWidth > 0; })()"
    )
    shown = page.evaluate(
        f"""(() => {{ const i = document.querySelector('{TWIN}');
        return {{ w: i.naturalWidth, h: i.naturalHeight, cw: i.clientWidth, ch: i.clientHeight,
                  fit: getComputedStyle(i).objectFit }}; }})()"""
    )
    # the element shows all of the image: nothing cropped by its box
    assert shown["fit"] in ("contain", "fill", "scale-down"), shown
    assert abs(shown["cw"] / shown["ch"] - shown["w"] / shown["h"]) < 0.02, shown

    with Image.open(io.BytesIO(page.locator(TWIN).screenshot())) as im:
        rgb = np.asarray(im.convert("RGB")).astype(int)
    height, width = rgb.shape[:2]
    background = rgb[height // 2, 6]  # the left edge, mid height: the render's background
    head = np.abs(rgb - background).sum(axis=-1) > 24
    inner = head[3:12, 12 : width - 12]  # the top rows inside the border and its rounded corners
    assert not inner.any(), (
        f"the head touches the top of the twin as shown ({int(inner[0].sum())} head pixels in the top row "
        f"of a {width}x{height} image)"
    )
    rows = np.flatnonzero(head[:, 12 : width - 12].any(axis=1))
    assert len(rows) and rows[0] < 0.2 * height, "the head is drawn small, far below the top"
