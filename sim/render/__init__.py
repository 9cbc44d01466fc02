"""Headless rendering of the digital twin: pyrender through EGL on the CPU (Mesa llvmpipe), no display.

`HeadRenderer` draws posed meshes or a head in a pose; `servoface.sim.render.images` lays images out (side by side,
labelled contact sheets); `...video` writes GIF / MP4 animations; `servoface.sim.render.twin` renders a
head posed from actuator targets (the twin's view of a command).
"""

from servoface.sim.render.backend import EGL_INSTALL_HINT, egl_missing_reason
from servoface.sim.render.renderer import HeadRenderer, parse_size
from servoface.sim.render.scene import MeshItem

__all__ = ["EGL_INSTALL_HINT", "HeadRenderer", "MeshItem", "egl_missing_reason", "parse_size"]
