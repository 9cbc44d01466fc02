"""A fast lossless PNG writer for the twin's 640x480 RGB frames.

Pillow's PNG encoder tries every row filter per row (adaptive filtering), which costs ~25 ms for a 640x480
frame here; the twin's frames (a face on a flat background) compress as well with the plain "Up" filter,
computed in one numpy subtraction, and zlib level 1: ~10 ms, files within a few percent of Pillow's size,
pixel for pixel the same image (tests/studio/test_render_worker.py decodes it with Pillow)."""

from __future__ import annotations

import struct
import zlib

import numpy as np
from numpy.typing import NDArray

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FILTER_NONE, FILTER_UP = 0, 2


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(rgb: NDArray[np.uint8], level: int = 1) -> bytes:
    """``rgb`` (H, W, 3) uint8 -> PNG bytes (8-bit RGB, no interlace), every row "Up"-filtered."""
    image = np.ascontiguousarray(rgb)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3 or image.shape[0] < 1 or image.shape[1] < 1:
        raise ValueError(f"expected an (H, W, 3) uint8 image, got {image.dtype} {image.shape}")
    height, width = image.shape[:2]
    rows = image.reshape(height, width * 3)
    raw = np.empty((height, width * 3 + 1), dtype=np.uint8)
    raw[:, 0] = FILTER_UP
    raw[0, 0] = FILTER_NONE
    raw[0, 1:] = rows[0]
    np.subtract(rows[1:], rows[:-1], out=raw[1:, 1:])  # uint8 wraps modulo 256, as the Up filter wants
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (
        PNG_SIGNATURE
        + _chunk(b"IHDR", header)
        + _chunk(b"IDAT", zlib.compress(raw.tobytes(), level))
        + _chunk(b"IEND", b"")
    )
