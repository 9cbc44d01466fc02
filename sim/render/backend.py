"""The offscreen OpenGL backend: pyrender through EGL on Mesa (llvmpipe on a CPU-only box).

Everything that touches pyrender's OpenGL state lives here. PyPI pyrender 0.1.45 is used as is, with two
changes made by subclassing its ``Renderer`` (never by editing the installed package):

* no multisampling: pyrender always renders into a 4x MSAA buffer and blits it; on llvmpipe that costs
  about a third of the frame. We render straight into a plain framebuffer instead.
* colour-only read-back: pyrender always reads and linearises the depth buffer; we read it only when a
  caller asks for depth.
* a lean fragment shader (``shaders/mesh.frag``: wrapped Lambert + Blinn-Phong) instead of pyrender's GGX
  PBR shader, which dominates the frame time on a CPU rasteriser.

pyrender's ``bounds``/``centroid``/``scale`` raise under numpy 2 (mmatl/pyrender#288); nothing here uses
them (they are only reached through shadow maps, which we never enable).
"""

from __future__ import annotations

import ctypes.util
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim.errors import RenderError

EGL_INSTALL_HINT = (
    "headless rendering needs EGL and Mesa's llvmpipe driver: "
    "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri (and run with PYOPENGL_PLATFORM=egl)"
)


def egl_missing_reason() -> str | None:
    """Why EGL rendering cannot work on this machine, or None if the EGL library is present.

    Only a missing system library counts: a present library that then fails is a real error, not a skip.
    """
    platform = os.environ.get("PYOPENGL_PLATFORM", "egl")
    if platform != "egl":
        return None
    if ctypes.util.find_library("EGL") is None:
        return f"libEGL not found. {EGL_INSTALL_HINT}"
    return None


def import_pyrender() -> Any:
    """Import pyrender for offscreen EGL rendering, or raise `RenderError` with an install hint."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    reason = egl_missing_reason()
    if reason is not None:
        raise RenderError(reason)
    try:
        import pyrender
    except Exception as err:  # OpenGL raises ImportError, AttributeError or RuntimeError here
        raise RenderError(
            f"cannot import pyrender/OpenGL for EGL rendering: {err}. {EGL_INSTALL_HINT}"
        ) from err
    return pyrender


SHADERS = Path(__file__).with_name("shaders")
MESH_FRAG = SHADERS / "mesh.frag"
MESH_VERT = SHADERS / "mesh.vert"


def _shader_cache(pyrender: Any) -> Any:
    """pyrender's shader cache with our lean ``mesh.frag`` instead of its PBR one; others unchanged."""
    base = pyrender.shader_program.ShaderProgramCache

    class LeanShaderCache(base):  # type: ignore[misc, valid-type]
        def get_program(
            self,
            vertex_shader: str,
            fragment_shader: str,
            geometry_shader: str | None = None,
            defines: dict[str, Any] | None = None,
        ) -> Any:
            if fragment_shader == "mesh.frag" and vertex_shader == "mesh.vert":
                # pyrender joins names onto its shader folder; an absolute path survives os.path.join
                vertex_shader, fragment_shader = str(MESH_VERT), str(MESH_FRAG)
            return super().get_program(vertex_shader, fragment_shader, geometry_shader, defines)

    return LeanShaderCache()


def _fast_renderer_class(pyrender: Any) -> type:
    """pyrender's Renderer without MSAA and with optional depth read-back (see module docstring)."""
    from OpenGL import GL

    base = pyrender.renderer.Renderer

    class FastRenderer(base):  # type: ignore[misc, valid-type]
        want_depth = True
        _main_fb: Any
        _main_fb_dims: tuple[Any, Any]

        def _configure_main_framebuffer(self) -> None:
            dims = (self.viewport_width, self.viewport_height)
            if self._main_fb is not None and self._main_fb_dims != dims:
                self._delete_main_framebuffer()
            if self._main_fb is not None:
                return
            self._main_cb, self._main_db = GL.glGenRenderbuffers(2)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_RGBA, *dims)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH_COMPONENT24, *dims)
            self._main_fb = GL.glGenFramebuffers(1)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
            GL.glFramebufferRenderbuffer(
                GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, self._main_cb
            )
            GL.glFramebufferRenderbuffer(
                GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, self._main_db
            )
            # pyrender draws into _main_fb_ms; point it at the single-sample buffer
            self._main_fb_ms = self._main_fb
            self._main_fb_dims = dims

        def _delete_main_framebuffer(self) -> None:
            if self._main_fb is not None:
                GL.glDeleteFramebuffers(1, [self._main_fb])
            if self._main_cb is not None:
                GL.glDeleteRenderbuffers(2, [self._main_cb, self._main_db])
            self._main_fb = self._main_fb_ms = None
            self._main_cb = self._main_db = None
            self._main_cb_ms = self._main_db_ms = None
            self._main_fb_dims = (None, None)

        def _sorted_mesh_nodes(self, scene: Any) -> list[Any]:
            # pyrender draws opaque meshes back to front; we draw them by ``draw_order`` (the skin first),
            # so the parts hidden under the skin fail the depth test early instead of being shaded
            solid: list[Any] = []
            clear: list[Any] = []
            for node in scene.mesh_nodes:
                (clear if node.mesh.is_transparent else solid).append(node)
            solid.sort(key=lambda n: getattr(n.mesh, "draw_order", 0))
            return solid + clear

        def _read_main_framebuffer(self, scene: Any, flags: int) -> tuple[Any, Any]:
            width, height = self._main_fb_dims
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
            depth = None
            if self.want_depth:
                raw = GL.glReadPixels(0, 0, width, height, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT)
                depth = _linear_depth(
                    np.frombuffer(raw, dtype=np.float32).reshape(height, width)[::-1],
                    scene.main_camera_node.camera.znear,
                    scene.main_camera_node.camera.zfar,
                )
            # RGBA is the framebuffer's own layout: reading it skips a per-pixel repack in the driver
            raw = GL.glReadPixels(0, 0, width, height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
            color = np.frombuffer(raw, dtype=np.uint8).reshape(height, width, 4)[::-1, :, :3]
            return np.ascontiguousarray(color), depth

    return FastRenderer


def _linear_depth(buf: NDArray[np.float32], znear: float, zfar: float) -> NDArray[np.float32]:
    """Window depth (0..1) to distance along the view axis (scene units); 0 where nothing was drawn."""
    ndc = 2.0 * buf.astype(np.float32) - 1.0
    empty = buf >= 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        out = (2.0 * znear * zfar) / (zfar + znear - ndc * (zfar - znear))
    out[empty] = 0.0
    return out.astype(np.float32)


class Offscreen:
    """One EGL context and pyrender renderer of a fixed size. Create, use and delete in one thread."""

    def __init__(self, width: int, height: int) -> None:
        self.pyrender = import_pyrender()
        try:
            self._osr = self.pyrender.OffscreenRenderer(width, height)
            self._osr._renderer.__class__ = _fast_renderer_class(self.pyrender)
            self._osr._renderer._program_cache = _shader_cache(self.pyrender)
            platform = self._osr._platform
            if hasattr(platform, "_egl_display"):
                platform.delete_context = lambda: _destroy_context_only(platform)
        except Exception as err:
            hint = egl_missing_reason() or EGL_INSTALL_HINT
            raise RenderError(
                f"cannot create a {width}x{height} EGL rendering context: {err}. {hint}"
            ) from err
        self.width = width
        self.height = height

    def make_current(self) -> None:
        self._osr._platform.make_current()

    def make_uncurrent(self) -> None:
        self._osr._platform.make_uncurrent()

    def render(self, scene: Any, depth: bool = False) -> tuple[NDArray[np.uint8], NDArray[np.float32] | None]:
        """Draw ``scene``: (H, W, 3) uint8 colour and, if asked, (H, W) float depth (0 = background)."""
        if self._osr is None:
            raise RenderError("the renderer was closed")
        self._osr._renderer.want_depth = depth
        try:
            color, depth_im = self._osr.render(scene)
        except Exception as err:
            raise RenderError(f"rendering a {self.width}x{self.height} frame failed: {err}") from err
        return color, depth_im

    def delete(self) -> None:
        """Free this renderer's GL objects and its context (other renderers keep working)."""
        if self._osr is not None:
            osr, self._osr = self._osr, None
            osr.delete()


def _destroy_context_only(platform: Any) -> None:
    """Replacement for pyrender's EGL ``delete_context``, which also calls ``eglTerminate`` on the display.

    Every context of the process shares that display, so terminating it when one renderer is deleted (or
    garbage-collected) breaks all the others (EGL_BAD_DISPLAY). We destroy only this context.
    """
    from OpenGL import EGL

    display, context = getattr(platform, "_egl_display", None), getattr(platform, "_egl_context", None)
    if display is not None and context is not None:
        EGL.eglMakeCurrent(display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
        EGL.eglDestroyContext(display, context)
    platform._egl_context = None
    platform._egl_display = None
