"""Headless rendering of the digital twin: pyrender through EGL on the CPU (Mesa llvmpipe), no display.

`HeadRenderer` draws posed meshes or a head in a pose; `sim.render.images` lays images out (side by side,
labelled contact sheets); `sim.render.video` writes GIF / MP4 animations; `sim.render.twin` renders a
head posed from actuator targets (the twin's view of a command).
"""

from sim.render.backend import EGL_INSTALL_HINT, egl_missing_reason
from sim.render.renderer import HeadRenderer, parse_size
from sim.render.scene import MeshItem

__all__ = ["EGL_INSTALL_HINT", "HeadRenderer", "MeshItem", "egl_missing_reason", "parse_size"]
