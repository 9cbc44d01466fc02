"""Contact sheets, side-by-side images, easing and the GIF / MP4 writers (no GL needed)."""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image as PILImage
from servoface.sim.render.images import contact_sheet, label_height, render_side_by_side, with_label
from servoface.sim.render.progress import progress
from servoface.sim.render.video import there_and_back, write_gif, write_mp4


def _img(value: int, h: int = 30, w: int = 40) -> np.ndarray:
    return np.full((h, w, 3), value, dtype=np.uint8)


def test_label_strip_holds_text() -> None:
    out = with_label(_img(100), "joy")
    strip = label_height(40)
    assert out.shape == (30 + strip, 40, 3)
    assert np.array_equal(out[:30], _img(100))
    assert out[30:].std() > 5  # text drawn on the strip


def test_contact_sheet_layout_and_errors() -> None:
    images = [_img(v) for v in (10, 60, 110, 160, 210)]
    sheet = contact_sheet(images, ["a", "b", "c", "d", "e"], columns=3, gap_px=2)
    cell_h = 30 + label_height(40)
    assert sheet.shape == (2 * cell_h + 3 * 2, 3 * 40 + 4 * 2, 3)
    assert np.all(sheet[2:32, 2:42] == 10)  # first image, top left
    assert np.all(sheet[2 + cell_h + 2 : 32 + cell_h + 2, 44:84] == 210)  # fifth: second row, second column
    with pytest.raises(ValueError, match="labels"):
        contact_sheet(images, ["a"])
    with pytest.raises(ValueError, match="differ in size"):
        contact_sheet([_img(1), _img(1, h=31)], ["a", "b"])
    with pytest.raises(ValueError, match="no images"):
        contact_sheet([], [])
    with pytest.raises(ValueError, match="uint8"):
        contact_sheet([np.zeros((4, 4, 3))], ["float"])


def test_side_by_side_puts_target_left_and_gated_right() -> None:
    both = render_side_by_side(_img(20), _img(220), ("target", "gated"))
    assert both[10, 10, 0] == 20 and both[10, both.shape[1] - 10, 0] == 220
    with pytest.raises(ValueError, match="same size"):
        render_side_by_side(_img(1), _img(1, w=41))


def test_there_and_back_eases_from_neutral_to_apex_and_back() -> None:
    w = there_and_back(2.0, 20.0)
    assert len(w) == 40 and w[0] == 0.0 and w[-1] == 0.0 and w.max() == 1.0
    peak = int(np.argmax(w))
    assert np.all(np.diff(w[: peak + 1]) >= 0) and np.all(np.diff(w[peak:]) <= 0)
    assert np.abs(np.diff(w)).max() < 0.2  # smooth: no jumps
    with pytest.raises(ValueError, match="duration"):
        there_and_back(0.0)
    with pytest.raises(ValueError, match="fps"):
        there_and_back(2.0, 0.5)


def _frames(n: int) -> list[np.ndarray]:
    return [_img(int(200 * k / (n - 1)), 31, 41) for k in range(n)]  # odd sizes on purpose


def test_gif_is_written_with_every_frame_and_its_timing(tmp_path: Path) -> None:
    path = tmp_path / "clip.gif"
    assert write_gif(_frames(12), path, fps=20) == 12
    with PILImage.open(path) as im:
        assert im.n_frames == 12 and im.size == (41, 31)
        durations = []
        for i in range(im.n_frames):
            im.seek(i)
            durations.append(im.info["duration"])
    assert sum(durations) == 12 * 50
    decoded = imageio.mimread(str(path))
    assert abs(int(decoded[-1][15, 20, 0]) - 200) <= 4 and int(decoded[0][15, 20, 0]) <= 4  # shared palette


def test_mp4_is_written_and_readable(tmp_path: Path) -> None:
    path = tmp_path / "clip.mp4"
    assert write_mp4(_frames(12), path, fps=20) == 12
    reader = imageio.get_reader(str(path))
    try:
        assert reader.count_frames() == 12
        first = reader.get_data(0)
        assert first.shape == (32, 42, 3)  # padded to even sides for yuv420p
        last = reader.get_data(11)
        assert abs(int(last[15, 20].mean()) - 200) < 12 and int(first[15, 20].mean()) < 15
    finally:
        reader.close()


def test_writers_reject_bad_frames(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="no frames"):
        write_gif([], tmp_path / "x.gif")
    with pytest.raises(ValueError, match="differs"):
        write_mp4([_img(1), _img(1, w=50)], tmp_path / "x.mp4")
    with pytest.raises(ValueError, match="fps"):
        write_gif(_frames(3), tmp_path / "x.gif", fps=0)


def test_progress_passes_items_through() -> None:
    assert list(progress(range(5), total=5, enabled=True)) == [0, 1, 2, 3, 4]
    assert list(progress(iter("ab"), enabled=False)) == ["a", "b"]
