"""The offscreen renderer on simple trimesh scenes: real EGL renders at small sizes."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import trimesh
from servoface.sim.errors import RenderError
from servoface.sim.render import HeadRenderer, MeshItem, parse_size
from servoface.sim.render.camera import BACKGROUND_RGB
from servoface.sim.render.materials import eye_vertex_colors, srgb_to_linear
from servoface.sim.render.normals import VertexNormals

W, H = 160, 120
SKIN = (0.86, 0.70, 0.60, 1.0)


def _translate(x: float, y: float, z: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


BALL = trimesh.creation.icosphere(subdivisions=3, radius=80.0)
EYE = trimesh.creation.icosphere(subdivisions=2, radius=12.0)
BOX = ((-90.0, -90.0, -90.0), (90.0, 90.0, 90.0))


def _face(eye_dx: float = 0.0) -> list[MeshItem]:
    return [
        MeshItem(BALL, SKIN, np.eye(4), "skin_ball"),
        MeshItem(EYE, (1, 1, 1, 1), _translate(28 + eye_dx, 20, 70), "eyeball_l"),
        MeshItem(EYE, (1, 1, 1, 1), _translate(-28 + eye_dx, 20, 70), "eyeball_r"),
    ]


def test_render_is_a_lit_face_coloured_image_on_the_background(renderer: HeadRenderer) -> None:
    img = renderer.render_meshes(_face(), box_mm=BOX)
    assert img.shape == (H, W, 3) and img.dtype == np.uint8
    bg = np.round(np.array(BACKGROUND_RGB) * 255)
    assert np.abs(img[0, 0].astype(float) - bg).max() <= 2  # corner: background
    lower_cheek = img[H * 3 // 4, W // 2].astype(int)  # below the eyes: skin, warm (r > g > b)
    assert lower_cheek[0] > lower_cheek[1] > lower_cheek[2] and lower_cheek[0] > 120
    assert img.reshape(-1, 3).std(axis=0).min() > 10  # not blank


def test_eyes_have_dark_pupils(renderer: HeadRenderer) -> None:
    img = renderer.render_meshes(_face(), box_mm=BOX).astype(int)
    # the darkest pixels of the image sit in the eye region (upper half), and are near black
    lum = img.sum(axis=2)
    y, x = np.unravel_index(np.argmin(lum), lum.shape)
    assert y < H // 2 and lum[y, x] < 150


def test_depth_is_distance_along_the_view_and_zero_on_background(renderer: HeadRenderer) -> None:
    color, depth = renderer.render_meshes_with_depth([MeshItem(BALL, SKIN, np.eye(4), "ball")], box_mm=BOX)
    cam = renderer.frame(*BOX)
    eye_to_centre = float(np.linalg.norm(cam.pose[:3, 3]))
    assert depth.shape == (H, W)
    assert depth[0, 0] == 0.0
    centre = depth[H // 2 - 2 : H // 2 + 3, W // 2 - 2 : W // 2 + 3]
    # the sphere's front surface is 80 mm nearer than its centre (camera slightly above: tolerance)
    assert np.all(np.abs(centre - (eye_to_centre - 80.0)) < 4.0)
    assert depth[depth > 0].min() >= eye_to_centre - 80.5


def test_moving_a_part_changes_the_image_and_repeats_exactly(renderer: HeadRenderer) -> None:
    a = renderer.render_meshes(_face(), box_mm=BOX)
    b = renderer.render_meshes(_face(eye_dx=6.0), box_mm=BOX)
    c = renderer.render_meshes(_face(), box_mm=BOX)
    assert np.abs(a.astype(int) - b).mean() > 0.5
    assert np.array_equal(a, c)


def test_skin_updated_in_place_matches_a_fresh_renderer(renderer: HeadRenderer) -> None:
    """The vertex buffer rewritten between frames gives exactly what a new renderer draws."""
    faces = BALL.faces
    squashed = BALL.vertices * (1.0, 0.8, 1.0) + (0.0, 0.0, 5.0)
    renderer.render_posed([], (BALL.vertices, faces, SKIN), box_mm=BOX)
    updated, _ = renderer.render_posed([], (squashed, faces, SKIN), box_mm=BOX)
    with HeadRenderer(W, H) as fresh:
        expected, _ = fresh.render_posed([], (squashed, faces, SKIN), box_mm=BOX)
    assert np.array_equal(updated, expected)
    first, _ = renderer.render_posed([], (BALL.vertices, faces, SKIN), box_mm=BOX)
    assert np.abs(first.astype(int) - updated).mean() > 1.0


def test_inside_of_the_skin_shows_as_a_dark_cavity(renderer: HeadRenderer) -> None:
    """Looking into an open shell shows its inside in the dark mouth-cavity colour, not the background."""
    cup = trimesh.creation.icosphere(subdivisions=3, radius=80.0)
    keep = cup.triangles_center[:, 2] < 40.0  # cut a hole facing the camera
    cup = trimesh.Trimesh(cup.vertices, cup.faces[keep], process=False)
    img, _ = renderer.render_posed([], (cup.vertices, cup.faces, SKIN), box_mm=BOX)
    centre = img[H // 2, W // 2].astype(int)
    assert centre[0] > 1.3 * centre[2] and centre.sum() < 260  # dark red, not the grey-blue background


def test_views_look_from_the_front_the_side_and_between(renderer: HeadRenderer) -> None:
    snout = [MeshItem(trimesh.creation.box((40.0, 40.0, 160.0)), SKIN, np.eye(4), "snout")]

    def width_px(view: str) -> int:
        img = renderer.render_meshes(snout, view=view, box_mm=BOX).astype(int)
        bg = np.round(np.array(BACKGROUND_RGB) * 255)
        row = np.abs(img[H // 2] - bg).sum(axis=1) > 10
        return int(row.sum())

    front, three_q, side = width_px("front"), width_px("three-quarter"), width_px("side")
    assert front < three_q < side  # a long box seen end-on, obliquely and broadside


def test_wrong_thread_and_closed_renderer_raise(renderer: HeadRenderer) -> None:
    errors: list[BaseException] = []

    def other() -> None:
        try:
            renderer.render_meshes(_face(), box_mm=BOX)
        except RenderError as err:
            errors.append(err)

    t = threading.Thread(target=other)
    t.start()
    t.join()
    assert len(errors) == 1 and "thread" in str(errors[0])
    r = HeadRenderer(32, 32)
    r.close()
    r.close()  # twice is fine
    with pytest.raises(RenderError, match="closed"):
        r.render_meshes(_face(), box_mm=BOX)


def test_bad_inputs_are_rejected(renderer: HeadRenderer) -> None:
    with pytest.raises(ValueError, match="view"):
        renderer.render_meshes(_face(), view="top", box_mm=BOX)
    with pytest.raises(ValueError, match="nothing to render"):
        renderer.render_meshes([])
    with pytest.raises(ValueError, match="skin vertices"):
        renderer.render_posed([], (np.full((3, 3), np.nan), np.array([[0, 1, 2]]), SKIN), box_mm=BOX)
    with pytest.raises(ValueError, match="4x4"):
        renderer.render_meshes([(BALL, SKIN, np.eye(3))])
    with pytest.raises(ValueError, match="size"):
        HeadRenderer(8, 8)


def test_parse_size() -> None:
    assert parse_size("640x480") == (640, 480)
    assert parse_size("320X240") == (320, 240)
    for bad in ("640", "axb", "640x480x2", "0x10", "99999x10"):
        with pytest.raises(ValueError):
            parse_size(bad)


def test_vertex_normals_match_trimesh_on_a_sphere() -> None:
    normals = VertexNormals(BALL.faces, len(BALL.vertices))(BALL.vertices)
    assert normals.dtype == np.float32
    radial = BALL.vertices / np.linalg.norm(BALL.vertices, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", normals, radial) > 0.999)
    with pytest.raises(ValueError):
        VertexNormals(np.array([[0, 1, 5]]), 3)


def test_colours_are_linearised_and_eyes_painted() -> None:
    assert np.allclose(srgb_to_linear((1.0, 0.0, 0.5)), (1.0, 0.0, 0.2140, 1.0), atol=1e-3)
    with pytest.raises(ValueError):
        srgb_to_linear((1.2, 0, 0))
    colours = eye_vertex_colors(EYE.vertices)
    front = np.argmax(EYE.vertices[:, 2])
    back = np.argmin(EYE.vertices[:, 2])
    assert colours[front, :3].max() < 0.05  # pupil
    assert colours[back, :3].min() > 0.8  # sclera


def test_missing_egl_is_a_render_error_with_an_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    import servoface.sim.render.backend as backend

    monkeypatch.setenv("PYOPENGL_PLATFORM", "egl")
    monkeypatch.setattr(backend.ctypes.util, "find_library", lambda name: None)
    assert "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri" in (backend.egl_missing_reason() or "")
    with pytest.raises(RenderError, match="libEGL not found"):
        HeadRenderer(32, 32)


def test_the_key_light_is_the_single_brightest() -> None:
    """The shader gives the specular highlight to the brightest light; it must be the key, uniquely."""
    from servoface.sim.render.camera import LIGHTS

    intensities = sorted((light.intensity for light in LIGHTS), reverse=True)
    key = next(light for light in LIGHTS if light.name == "key")
    assert key.intensity == intensities[0] > intensities[1]


def test_lean_forward_pass_draws_exactly_what_pyrenders_pass_draws(renderer: HeadRenderer) -> None:
    glass = MeshItem(trimesh.creation.box((150.0, 30.0, 30.0)), (0.9, 0.9, 0.2, 0.5), np.eye(4), "glass")
    flap = trimesh.Trimesh(BALL.vertices, BALL.faces[BALL.triangles_center[:, 2] > 30.0], process=False)
    items = [*_face(), glass, MeshItem(flap, (0.3, 0.5, 0.8, 1.0), _translate(0, 0, 20), "open_flap")]
    skin = (BALL.vertices * 0.5, BALL.faces, SKIN)
    gl_renderer = renderer._gl._osr._renderer  # the subclassed pyrender Renderer (servoface.sim.render.backend)
    lean, _ = renderer.render_posed(items, skin, box_mm=BOX)
    gl_renderer.lean_forward_pass = False
    try:
        reference, _ = renderer.render_posed(items, skin, box_mm=BOX)
    finally:
        gl_renderer.lean_forward_pass = True
    # pyrender sums the lights in a set's order, we in a fixed one: float rounding may differ by a level
    diff = np.abs(lean.astype(int) - reference)
    assert diff.max() <= 2 and (diff > 0).mean() < 0.002
    assert np.abs(lean.astype(int) - renderer.render_meshes(_face(), box_mm=BOX)).mean() > 1  # all were drawn
