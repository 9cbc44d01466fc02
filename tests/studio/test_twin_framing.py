"""The studio's twin shows the whole head: real renders from the studio's render process (EGL on CPU), for
both built-in heads, read back from the PNGs the page is sent."""

from __future__ import annotations

import io

import numpy as np
import pytest
from numpy.typing import NDArray
from PIL import Image
from servoface.controller.studio.render_worker import RenderWorker

HEIGHT_PX = 480
TOP_BAND_PX = 10  # rows at the top that must be background: the silhouette stays clear of the edge
# the AUs that raise the top of the head most: brows and lids up (human), ears up and head up (dog)
RAISED = {"human": {"AU1": 1.0, "AU2": 1.0, "AU5": 0.7, "AU26": 1.0}, "dog": {"AU6": 1.0, "AU9": 0.4}}


def _decode(png: bytes) -> NDArray[np.uint8]:
    with Image.open(io.BytesIO(png)) as im:
        return np.asarray(im.convert("RGB"))


def silhouette(rgb: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """(H, W) bool: pixels that are not the flat background (the commonest colour of the side edges)."""
    edges = np.concatenate([rgb[:, 0], rgb[:, -1]])
    colours, counts = np.unique(edges, axis=0, return_counts=True)
    background = colours[np.argmax(counts)].astype(int)
    return np.abs(rgb.astype(int) - background).sum(axis=-1) > 12


@pytest.fixture(scope="module", params=["human", "dog"])
def head_worker(request: pytest.FixtureRequest):  # type: ignore[no-untyped-def]
    from servoface.controller.service import open_head

    opened = open_head(request.param, emulate=True, wire_time=False)
    worker = RenderWorker(opened.head, opened.pipeline.calibration, 0.02, 640, HEIGHT_PX)
    yield request.param, worker
    worker.close()
    opened.chain.close()


def test_the_twin_shows_the_top_of_the_head_with_a_margin(head_worker) -> None:  # type: ignore[no-untyped-def]
    name, worker = head_worker
    for op, aus in (("target", {}), ("target", RAISED[name]), ("still", RAISED[name])):
        mask = silhouette(_decode(worker.png(op, aus)))
        rows = np.flatnonzero(mask.any(axis=1))
        assert len(rows), f"{name} {op} {aus}: nothing drawn"
        assert not mask[:TOP_BAND_PX].any(), (
            f"{name} {op} {aus}: the head touches the image's top edge "
            f"({int(mask[0].sum())} head pixels in the top row, first head row {rows[0]})"
        )


def test_the_whole_head_still_fills_the_picture(head_worker) -> None:  # type: ignore[no-untyped-def]
    """The margin is small: the crown is near the top and the head fills most of the height."""
    name, worker = head_worker
    mask = silhouette(_decode(worker.png("target", {})))
    rows = np.flatnonzero(mask.any(axis=1))
    assert rows[0] < 0.2 * HEIGHT_PX, f"{name}: {rows[0]} px of background above the head"
    assert rows[-1] - rows[0] > 0.75 * HEIGHT_PX, f"{name}: the head is only {rows[-1] - rows[0]} px tall"
