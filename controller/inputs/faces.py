"""Several faces per frame (py-feat writes one row per detected face, MediaPipe one blendshape list per face):
follow ONE person instead of interleaving everybody's AUs.

Default (``face_id=None``): in the first frame, the largest face (by its box; the first one without boxes);
after that, in every frame the face whose box centre is nearest the followed face's last centre (a person
does not jump across the picture in one frame). ``face_id=k``: the k-th face of each frame counted from the
left by box (in the order written without boxes); a frame without a k-th face counts as "no face".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class FaceBox:
    x: float
    y: float
    w: float
    h: float

    @property
    def centre(self) -> tuple[float, float]:
        return (self.x + self.w / 2, self.y + self.h / 2)

    @property
    def area(self) -> float:
        return abs(self.w * self.h)


class FaceFollower:
    """Pick one face per frame; ``describe()`` says what was seen and followed."""

    def __init__(self, face_id: int | None = None) -> None:
        self.face_id = face_id
        self._last: tuple[float, float] | None = None
        self.most = 0
        self.multi_frames = 0
        self.frames = 0
        self.switches = 0

    def pick(self, boxes: Sequence[FaceBox | None]) -> int | None:
        """Index into ``boxes`` (one per face of this frame) of the face to follow, None if absent."""
        n = len(boxes)
        self.frames += 1
        self.most = max(self.most, n)
        self.multi_frames += n > 1
        if n == 0:
            return None
        have_boxes = all(b is not None for b in boxes)
        if self.face_id is not None:
            order = list(range(n))
            if have_boxes:
                order.sort(key=lambda i: boxes[i].x)  # type: ignore[union-attr]
            return order[self.face_id] if self.face_id < n else None
        if n == 1 or not have_boxes:
            return 0
        if self._last is None:
            best = max(range(n), key=lambda i: boxes[i].area)  # type: ignore[union-attr]
        else:
            lx, ly = self._last
            best = min(range(n), key=lambda i: _dist2(boxes[i].centre, (lx, ly)))  # type: ignore[union-attr]
        self._last = boxes[best].centre  # type: ignore[union-attr]
        return best

    def note_single(self, box: FaceBox | None) -> None:
        """The frame had only the face at ``box``: keep tracking its position."""
        if box is not None:
            self._last = box.centre

    def describe(self) -> str:
        if self.most <= 1:
            return ""
        rule = (
            f"followed face {self.face_id} (counted from the left)"
            if self.face_id is not None
            else "followed one person (largest face first, then the nearest box each frame; --face-id K picks "
            "the K-th from the left)"
        )
        return f"up to {self.most} faces per frame ({self.multi_frames} of {self.frames} frames); {rule}"


def _dist2(a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2
