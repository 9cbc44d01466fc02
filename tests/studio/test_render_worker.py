"""The studio's render process and its PNG writer: real renders (EGL on CPU), decoded with Pillow."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image
from servoface.controller.studio.png import encode_png
from servoface.controller.studio.render_worker import RenderWorker, RenderWorkerError


def _decode(png: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(png)) as im:
        assert im.mode == "RGB"
        return np.asarray(im)


def test_png_is_lossless_for_any_image() -> None:
    rng = np.random.default_rng(7)
    for shape in ((1, 1, 3), (2, 5, 3), (480, 640, 3)):
        rgb = rng.integers(0, 256, size=shape, dtype=np.uint8)
        assert np.array_equal(_decode(encode_png(rgb)), rgb)
    with pytest.raises(ValueError, match="uint8"):
        encode_png(np.zeros((4, 4), dtype=np.uint8))


@pytest.fixture(scope="module")
def worker():  # type: ignore[no-untyped-def]
    from servoface.controller.service import open_head

    opened = open_head("human", emulate=True, wire_time=False)
    w = RenderWorker(opened.head, opened.pipeline.calibration, 0.02, 640, 480)
    yield w, opened
    w.close()
    assert not w.alive


def test_worker_draws_the_face_and_survives_a_bad_request(worker) -> None:  # type: ignore[no-untyped-def]
    w, opened = worker
    neutral = _decode(w.png("target", {}))
    assert neutral.shape == (480, 640, 3)
    assert len(np.unique(neutral.reshape(-1, 3), axis=0)) > 50  # a shaded face, not a blank frame
    smile = _decode(w.png("target", {"AU12": 1.0, "AU26": 0.8}))
    assert np.abs(smile.astype(int) - neutral.astype(int)).sum() > 0
    still = _decode(w.png("still", {"AU26": 0.8}))
    assert still.shape == (480, 640, 3)
    with pytest.raises(RenderWorkerError, match="unknown render request"):
        w.png("nonsense", {})
    assert w.alive
    assert _decode(w.png("target", {})).shape == (480, 640, 3)
