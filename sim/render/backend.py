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

import ctypes
import ctypes.util
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.errors import RenderError

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
        raise RenderError(f"cannot import pyrender/OpenGL for EGL rendering: {err}. {EGL_INSTALL_HINT}") from err
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
    from pyrender.constants import GLTF, ProgramFlags
    from pyrender.constants import RenderFlags as RF

    GLTF_TRIANGLES = GLTF.TRIANGLES
    base = pyrender.renderer.Renderer

    class FastRenderer(base):  # type: ignore[misc, valid-type]
        want_depth = True
        lean_forward_pass = True  # False: pyrender's own pass (the tests compare the two pixel for pixel)
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

        def _forward_pass(self, scene: Any, flags: int, seg_node_map: Any = None) -> Any:
            """pyrender's forward pass with its per-draw Python overhead cut: per-frame uniforms (camera,
            lights) are set once per program per frame, uniform locations are cached, and GL state that
            never changes here is set once. Anything unusual (segmentation, depth-only, textures, spot or
            point lights) goes through pyrender's own pass."""
            nodes = [n for n in self._sorted_mesh_nodes(scene) if n.mesh.is_visible]
            plain = not (flags & (RF.SEG | RF.DEPTH_ONLY | RF.FLAT | RF.ALL_WIREFRAME | RF.FLIP_WIREFRAME))
            plain = plain and not scene.spot_light_nodes and not scene.point_light_nodes
            plain = plain and all(
                p.material.tex_flags == 0 and not p.material.wireframe and p.mode == GLTF_TRIANGLES
                for n in nodes
                for p in n.mesh.primitives
            )
            if not plain or not self.lean_forward_pass:
                return super()._forward_pass(scene, flags, seg_node_map)
            self._configure_forward_pass_viewport(flags)
            GL.glClearColor(*scene.bg_color)
            GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
            GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
            GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
            GL.glEnable(GL.GL_BLEND)
            GL.glCullFace(GL.GL_BACK)
            view_m, proj_m = self._get_camera_matrices(scene)
            cam_pos = scene.get_pose(scene.main_camera_node)[:3, 3]
            lights = []
            # a fixed light order (pyrender's is a set's): the same float sums, the same pixels, every run
            ordered = sorted(scene.directional_light_nodes, key=lambda ln: (str(ln.name), -ln.light.intensity))
            for ln in ordered[: self._compute_max_n_lights(flags)[0]]:
                lights.append((-scene.get_pose(ln)[:3, 2], ln.light.color, float(ln.light.intensity)))
            ready: set[int] = set()
            program = None
            for node in nodes:
                pose = scene.get_pose(node)
                for prim in node.mesh.primitives:
                    program = self._get_primitive_program(prim, flags, ProgramFlags.USE_MATERIAL)
                    program._bind()
                    u = _Uniforms.of(program)
                    if id(program) not in ready:
                        ready.add(id(program))
                        u.mat4("V", view_m)
                        u.mat4("P", proj_m)
                        u.vec("cam_pos", cam_pos)
                        u.vec("ambient_light", scene.ambient_light)
                        u.int("n_directional_lights", len(lights))
                        for i, (direction, color, intensity) in enumerate(lights):
                            u.vec(f"directional_lights[{i}].direction", direction)
                            u.vec(f"directional_lights[{i}].color", color)
                            u.float(f"directional_lights[{i}].intensity", intensity)
                    material = prim.material
                    u.mat4("M", pose)
                    u.vec("material.emissive_factor", material.emissiveFactor)
                    u.vec("material.base_color_factor", material.baseColorFactor)
                    u.float("material.metallic_factor", float(material.metallicFactor))
                    u.float("material.roughness_factor", float(material.roughnessFactor))
                    if material.alphaMode == "BLEND":
                        GL.glBlendFunc(GL.GL_SRC_ALPHA, GL.GL_ONE_MINUS_SRC_ALPHA)
                    else:
                        GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
                    if material.doubleSided:
                        GL.glDisable(GL.GL_CULL_FACE)
                    else:
                        GL.glEnable(GL.GL_CULL_FACE)
                    prim._bind()
                    n_instances = 1 if prim.poses is None else len(prim.poses)
                    if prim.indices is not None:
                        GL.glDrawElementsInstanced(
                            prim.mode, prim.indices.size, GL.GL_UNSIGNED_INT, ctypes.c_void_p(0), n_instances
                        )
                    else:
                        GL.glDrawArraysInstanced(prim.mode, 0, len(prim.positions), n_instances)
                    prim._unbind()
            if program is not None:
                program._unbind()
            GL.glFlush()
            return self._read_main_framebuffer(scene, flags)

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


class _Uniforms:
    """Uniform setters for one shader program with cached locations (pyrender looks each one up per call).

    Names the program does not use (location -1) are skipped, as pyrender does.
    """

    def __init__(self, program_id: int) -> None:
        from OpenGL import GL

        self._gl = GL
        self._id = program_id
        self._loc: dict[str, int] = {}

    @classmethod
    def of(cls, program: Any) -> _Uniforms:
        cached = getattr(program, "_servoface_uniforms", None)
        if cached is None or cached._id != program._program_id:
            cached = cls(program._program_id)
            program._servoface_uniforms = cached
        return cached

    def _where(self, name: str) -> int:
        loc = self._loc.get(name)
        if loc is None:
            loc = int(self._gl.glGetUniformLocation(self._id, name))
            self._loc[name] = loc
        return loc

    def mat4(self, name: str, value: Any) -> None:
        loc = self._where(name)
        if loc != -1:
            self._gl.glUniformMatrix4fv(loc, 1, self._gl.GL_TRUE, np.asarray(value, dtype=np.float32))

    def vec(self, name: str, value: Any) -> None:
        loc = self._where(name)
        if loc != -1:
            v = np.asarray(value, dtype=np.float32).ravel()
            setter = {2: self._gl.glUniform2fv, 3: self._gl.glUniform3fv, 4: self._gl.glUniform4fv}[len(v)]
            setter(loc, 1, v)

    def float(self, name: str, value: float) -> None:
        loc = self._where(name)
        if loc != -1:
            self._gl.glUniform1f(loc, value)

    def int(self, name: str, value: int) -> None:
        loc = self._where(name)
        if loc != -1:
            self._gl.glUniform1i(loc, value)


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
            raise RenderError(f"cannot create a {width}x{height} EGL rendering context: {err}. {hint}") from err
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
