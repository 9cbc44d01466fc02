"""Laying rendered images out: labels, side-by-side comparisons and contact sheets (Pillow)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image as PILImage
from PIL import ImageDraw, ImageFont
from servoface.sim.render.atomic import atomic_output

Image = NDArray[np.uint8]  # (H, W, 3)
SHEET_BG = (28, 30, 34)
LABEL_FG = (235, 235, 235)
LABEL_BG = (28, 30, 34)


@lru_cache(maxsize=8)
def _font(size_px: int) -> Any:
    try:
        return ImageFont.load_default(size=size_px)  # Pillow >= 10.1: a scalable font, no system fonts needed
    except TypeError:
        return ImageFont.load_default()


def _check_image(img: Any, what: str) -> Image:
    arr = np.asarray(img)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.dtype != np.uint8:
        raise ValueError(f"{what}: expected an (H, W, 3) uint8 image, got {arr.shape} {arr.dtype}")
    return arr


def label_height(width_px: int) -> int:
    """Height of the label strip under an image of ``width_px`` (scales with the image, 12..28 px)."""
    return int(np.clip(round(width_px * 0.09), 12, 28))


def with_label(img: Image, label: str) -> Image:
    """``img`` with a strip underneath holding ``label`` centred (shrunk to fit the width)."""
    arr = _check_image(img, f"image {label!r}")
    h, w = arr.shape[:2]
    strip = label_height(w)
    canvas = PILImage.new("RGB", (w, h + strip), LABEL_BG)
    canvas.paste(PILImage.fromarray(arr), (0, 0))
    draw = ImageDraw.Draw(canvas)
    size = strip - 4
    font = _font(size)
    while size > 7 and draw.textlength(label, font=font) > w - 4:
        size -= 1
        font = _font(size)
    text_w = draw.textlength(label, font=font)
    draw.text(((w - text_w) / 2, h + (strip - size) / 2 - 1), label, fill=LABEL_FG, font=font)
    return np.asarray(canvas, dtype=np.uint8)


def render_side_by_side(
    left: Image, right: Image, labels: Sequence[str] = ("target", "gated"), gap_px: int = 4
) -> Image:
    """Two images next to each other, each labelled (e.g. the target face and the gated, achievable one)."""
    if len(labels) != 2:
        raise ValueError(f"labels: expected 2 labels (left, right), got {len(labels)}")
    a, b = _check_image(left, "left"), _check_image(right, "right")
    if a.shape != b.shape:
        raise ValueError(f"left and right must have the same size, got {a.shape} and {b.shape}")
    return contact_sheet([a, b], list(labels), columns=2, gap_px=gap_px)


def contact_sheet(images: Sequence[Image], labels: Sequence[str], columns: int = 4, gap_px: int = 4) -> Image:
    """A grid of equally sized images, each with its label underneath, row by row, in the order given."""
    if not images:
        raise ValueError("contact_sheet: no images given")
    if len(labels) != len(images):
        raise ValueError(f"contact_sheet: {len(images)} images but {len(labels)} labels")
    if columns < 1:
        raise ValueError(f"contact_sheet: columns must be >= 1, got {columns}")
    cells = [
        with_label(_check_image(img, f"image {i} ({lab!r})"), lab)
        for i, (img, lab) in enumerate(zip(images, labels, strict=True))
    ]
    shapes = {c.shape for c in cells}
    if len(shapes) != 1:
        raise ValueError(f"contact_sheet: images differ in size: {sorted(s[:2] for s in shapes)}")
    ch, cw = cells[0].shape[:2]
    columns = min(columns, len(cells))
    rows = -(-len(cells) // columns)
    sheet = np.empty((rows * ch + (rows + 1) * gap_px, columns * cw + (columns + 1) * gap_px, 3), np.uint8)
    sheet[:] = SHEET_BG
    for i, cell in enumerate(cells):
        r, c = divmod(i, columns)
        y, x = gap_px + r * (ch + gap_px), gap_px + c * (cw + gap_px)
        sheet[y : y + ch, x : x + cw] = cell
    return sheet


def save_image(img: Image, path: Any) -> None:
    """Write an image (PNG or JPEG by the file's extension), all or nothing: a failed write (or Ctrl-C)
    leaves no truncated file, and a file already at ``path`` as it was. A file object is written as is."""
    pil = PILImage.fromarray(_check_image(img, str(path)))
    if not isinstance(path, str | os.PathLike):
        pil.save(path)
        return
    with atomic_output(path) as tmp:
        pil.save(tmp)  # keeps the target's suffix: Pillow picks the format by it
