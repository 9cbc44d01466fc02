"""Procedural meshes of the built-in ``dog`` head, after Londra (mesaticephalic, Staffordshire-terrier-like).

The skin is a loft of cross-sections along the head's length (+z towards the nose). Each ring is split at
the mouth line on both sides, and the last ring collapses onto the front of the mouth, so upper lip
(flews) and lower lip/chin share rest positions but not faces: the lower part follows the jaw and the
mouth opens; raising the flews (snarl) shows the teeth behind them. The nose pad, the eye openings and
the muzzle are carved in the same loft; the eye openings' rims are then laid on their ellipses
(`servoface.sim.heads.opening`), so the skin's edge round each eye is a smooth curve, not a grid's
stair-step. Rigid parts: skull, jaw with lower teeth, upper teeth, eyeballs (iris, pupil), upper lids,
cropped erect ears, a two-segment tongue, neck, mouth cavity and eye sockets.

Design coordinates put the atlas at (0, 70, -50); every mesh is shifted by ``OFFSET`` so that the head
frame's origin is the top of the neck, as for every head.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from servoface.sim.heads import mesh_tools as mt
from servoface.sim.heads import opening
from servoface.sim.heads.mesh_tools import F64, I64

OFFSET = np.array([0.0, -70.0, 50.0])

# design coordinates (before OFFSET)
_EYE_L = np.array([27.0, 118.0, 68.0])
EYE_RADIUS = 11.0
_EYE_HOLE = (12.0, 8.0)  # half-sizes of the skin opening, in the eye's own frame
EYE_YAW_DEG = 28.0  # the eyes look this far out to the side at rest (dogs' eyes diverge)
_JAW_PIVOT = np.array([0.0, 84.0, 8.0])
EYE_CENTRE_L = tuple(float(v) for v in _EYE_L + OFFSET)
JAW_PIVOT = tuple(float(v) for v in _JAW_PIVOT + OFFSET)

SKIN_RGBA = (0.80, 0.62, 0.45, 1.0)  # fawn
NOSE_RGBA = (0.08, 0.07, 0.07, 1.0)
LIP_RGBA = (0.20, 0.14, 0.13, 1.0)
MUZZLE_RGBA = (0.93, 0.90, 0.84, 1.0)  # white blaze on the muzzle

# profile tables along z (design coordinates)
_Z = np.array([-78, -62, -35, -5, 25, 50, 70, 95, 120, 138, 146, 151, 154, 156, 157.0])
_TOP = np.array([104, 138, 158, 162, 156, 140, 126, 122, 120, 117, 113, 105, 95, 85, 78.0])
_YC = np.array([96, 92, 88, 85, 82, 79, 78, 78, 78, 78, 78, 78, 78, 78, 78.0])
_BOT = np.array([86, 58, 42, 36, 40, 50, 56, 60, 62, 64, 67, 70, 73, 76, 78.0])
_W = np.array([18, 50, 62, 67, 66, 56, 43, 38, 35, 32, 29, 26, 23, 20, 18.0])
MOUTH_CORNER_Z = 78.0


def _stations(n: int) -> F64:
    """Station z values (design coords): even in arc length of the profile, denser on the muzzle."""
    zz = np.linspace(_Z[0], _Z[-1], 6000)
    top, _, bot, w = (np.interp(zz, _Z, t) for t in (_TOP, _YC, _BOT, _W))
    step = np.hypot(np.diff(zz), np.abs(np.diff(top)) + np.abs(np.diff(bot)) + np.abs(np.diff(w)))
    dens = 1.0 + 0.8 * mt.smoothstep((zz[1:] - 40.0) / 30.0)
    s = np.concatenate([[0.0], np.cumsum(step * dens)])
    return np.asarray(np.interp(np.linspace(0.0, s[-1], n), s, zz), dtype=np.float64)


def _ring_params(z: F64) -> tuple[F64, F64, F64, F64]:
    return np.interp(z, _Z, _TOP), np.interp(z, _Z, _YC), np.interp(z, _Z, _BOT), np.interp(z, _Z, _W)


def _surface(z: F64, u: F64) -> F64:
    """(..., 3) skin points (design coordinates) at station ``z`` (mm along the head) and angle ``u`` (rad
    round the ring: 0 = top, +pi/2 = the head's left); arrays of one shape. The skin is this surface on a
    grid of stations and angles, so a vertex moved in (z, u) stays on it."""
    z = np.asarray(z, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    top, yc, bot, w = _ring_params(z)
    su, cu = np.sin(u), np.cos(u)
    upper = cu >= 0
    e_up, e_lo = 0.62, 0.85
    h = np.where(upper, top - yc, yc - bot)
    e = np.where(upper, e_up, e_lo)
    x = w * np.sign(su) * np.abs(su) ** e
    # towards the tip the rings flatten onto the mouth's front edge: spread their points evenly along it
    x_even = w * np.sign(su) * (1.0 - np.abs(1.0 - 2.0 * np.abs(u) / np.pi))
    even = mt.smoothstep((z - (_Z[-1] - 14.0)) / 14.0)
    x = (1.0 - even) * x + even * x_even
    y = yc + h * np.sign(cu) * np.abs(cu) ** e
    station = z
    # Staffy cheeks: bulge the lower sides behind the mouth corner
    x = x * (1.0 + 0.10 * mt.gauss2(z - 15.0, (y - 70.0), 30.0, 22.0))
    # chin recedes below the mouth line near the front
    below = np.clip((yc - y) / 14.0, 0.0, 1.0)
    z = z - 9.0 * below * mt.smoothstep((station - 110.0) / 40.0)
    # nostrils and nose pad shape: a slight dip on each side of the front face
    frontness = mt.smoothstep((station - 148.0) / 6.0)
    nostril = mt.gauss2(np.abs(x) - 8.0, y - 99.0, 4.0, 3.0)
    z = z - 3.0 * nostril * frontness
    # brow: a bump above each eye, a central furrow on the stop
    ax = np.abs(x)
    x = x + np.sign(x) * 3.0 * mt.gauss2(z - 40.0, y - 130.0, 14.0, 8.0)
    y = y + 4.0 * mt.gauss2(ax - 30.0, z - 52.0, 12.0, 10.0)
    y = y - 3.0 * mt.gauss2(ax, z - 45.0, 6.0, 14.0)
    return np.stack([x, y, z], -1)


@lru_cache(maxsize=1)
def _skin() -> tuple[F64, I64, F64]:
    ns, nu = 58, 88  # nu divisible by 4: columns at +-90 deg lie on the mouth line
    zs = _stations(ns)
    u = (np.arange(nu) - nu // 2) * (2.0 * np.pi / nu)  # 0 = top, +pi/2 = head's left (+x); exactly odd
    grid_z, grid_u = np.broadcast_arrays(zs[:, None], u[None, :])
    nz = len(zs)
    verts = _surface(grid_z, grid_u).reshape(-1, 3)
    faces = mt.grid_faces(nz, nu, periodic_u=True)[:, ::-1]
    n_grid = len(faces)
    back = len(verts)
    verts = np.concatenate([verts, [[0.0, 100.0, -82.0]]])
    faces = np.concatenate([faces, mt.fan(np.arange(nu), back)])
    tri = verts[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    if float(np.sum(n * (tri.mean(1) - np.array([0.0, 95.0, 30.0])))) < 0:
        faces = faces[:, ::-1].copy()

    # the last ring is a segment: drop its zero-area faces, then split the mouth
    ring_of = np.arange(len(verts)) // nu
    col_of = np.arange(len(verts)) % nu
    ring_of[back] = -1
    lower_col = np.abs(u) > np.pi / 2 + 1e-9
    side_col = np.isclose(np.abs(u), np.pi / 2)
    # eye openings, in each eye's own frame, decided per grid quad so both sides match; the stair-step rim
    # this leaves is laid on the opening's ellipse below (`_smooth_eye_rims`)
    cen = mt.quad_centres(verts, faces, n_grid)
    hole = np.zeros(len(faces), dtype=bool)
    for sx in (1.0, -1.0):
        local = (cen - _eye(sx)) @ _eye_rot(sx)
        r = (local[:, 0] / _EYE_HOLE[0]) ** 2 + (local[:, 1] / _EYE_HOLE[1]) ** 2
        hole |= (r < 1.0) & (local[:, 2] > 0.0) & (local[:, 2] < 30.0)
    # vertices on the mouth line: side columns from the corner forward, and the whole last ring
    last = nz - 1
    zr = zs[np.clip(ring_of, 0, None)]
    on_line = ((ring_of >= 0) & side_col[col_of] & (zr > MOUTH_CORNER_Z)) | (ring_of == last)
    on_line[back] = False
    # a grid quad is "lower" when all four corners lie in lower columns or on the line (not all on it);
    # deciding per quad keeps the slit mirror-symmetric whatever the triangle diagonals
    fl = lower_col[col_of[faces]] | on_line[faces]
    f_low = fl.all(1) & ~(ring_of[faces] == -1).any(1) & ~on_line[faces].all(1)
    corners = mt.quad_corners(faces, n_grid)
    ok = lower_col[col_of[corners]] | on_line[corners]
    quad_low = ok.all(1) & ~on_line[corners].all(1)
    f_low[:n_grid] = np.repeat(quad_low, 2)
    f_low &= on_line[faces].any(1)
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    keep = (area > 1e-9) & ~hole
    faces = opening.swap_ear_diagonals(faces, n_grid, keep)
    faces, f_low = faces[keep], f_low[keep]
    params = np.concatenate([np.stack([grid_z, grid_u], -1).reshape(-1, 2), [[np.nan, np.nan]]])  # back: none
    verts[:back] = _surface(*_smooth_eye_rims(verts, faces, params[:back], nu).T)
    weights = _colour_weights(verts, faces[(faces < back).all(1)])
    # the upper lip keeps the line's vertices; the lower lip gets copies (of their colour weights too)
    ids = np.nonzero(on_line)[0]
    verts, faces, _ = mt.split_vertices(verts, faces, ids, f_low)
    weights = np.concatenate([weights, weights[ids]])

    verts, faces, (kept,) = mt.compact(verts, faces, weights)
    weights = np.asarray(kept, dtype=np.float64)

    col = np.tile(np.array(SKIN_RGBA), (len(verts), 1))
    for k, rgba in enumerate((MUZZLE_RGBA, LIP_RGBA, NOSE_RGBA)):
        wgt = weights[:, k]
        col = col * (1.0 - wgt[:, None]) + np.array(rgba) * wgt[:, None]
    return verts + OFFSET, faces, col


_COLOUR_BLEND_ROUNDS = 3  # passes of `mt.blend_vertex_values` over the nose's and lips' colour weights
_COLOUR_GAIN = (1.3, 1.8)  # the nose's and the lips' blended weights are scaled by these (then capped at 1)


def _colour_weights(verts: F64, faces: I64) -> F64:
    """(n, 3) weights of the blaze, lip and nose colours at the skin's vertices (design coordinates).

    The nose pad's and the lips' edges are sharper (1.5..3 mm) than the skin's grid is fine there (rings
    3.5 mm apart on the nose's front, columns up to 8 mm apart above the mouth line); coloured per vertex,
    such an edge is drawn along the grid's triangles, a saw-tooth (session 36). Their weights are blended
    over the grid's edges, so each edge spans a couple of grid cells wherever the grid runs and is drawn as
    a smooth curve. The blaze's edges are soft enough already."""
    vx, vy, vz = verts[:, 0], verts[:, 1], verts[:, 2]
    yc_v = np.interp(vz, _Z, _YC)
    blaze = mt.smoothstep((9.0 - np.abs(vx)) / 4.0) * mt.smoothstep((vy - yc_v - 22.0) / 6.0)
    blaze = blaze * mt.smoothstep((vz - 40.0) / 15.0) * mt.smoothstep((140.0 - vz) / 6.0)
    nose = mt.smoothstep((vz - 141.0) / 3.0) * mt.smoothstep((vy - 91.0) / 2.5)
    lips = mt.smoothstep((vz - MOUTH_CORNER_Z + 4.0) / 4.0) * mt.smoothstep((3.5 - np.abs(vy - yc_v)) / 1.5)
    soft = mt.blend_vertex_values(np.stack([nose, lips], 1), faces, _COLOUR_BLEND_ROUNDS)
    # blending lowers a thin band's middle (the lips' most): a gain brings the full colour back inside. Only
    # a gentle one: sharpening the blended edge again (to under ~2 grid cells) brings the saw-tooth back
    soft = np.minimum(soft * np.array(_COLOUR_GAIN), 1.0)
    return np.stack([blaze, soft[:, 1], soft[:, 0]], 1)


def _hole_coords(side: float, points: F64) -> F64:
    """(..., 2) coordinates of points in an eye's frame in which the skin's eye opening is the unit circle."""
    local = (points - _eye(side)) @ _eye_rot(side)
    return np.asarray(local[..., :2] / np.array(_EYE_HOLE), dtype=np.float64)


def _near_eye(side: float, points: F64) -> NDArray[np.bool_]:
    local = (points - _eye(side)) @ _eye_rot(side)
    return np.asarray((np.abs(local[:, 0]) < 25.0) & (np.abs(local[:, 1]) < 20.0) & (local[:, 2] > -10.0))


def _smooth_eye_rims(verts: F64, faces: I64, params: F64, nu: int) -> F64:
    """New (z, u) params (n, 2) of the grid vertices (n = rings x nu): the left eye's opening smoothed
    (`opening.smooth_opening`) and mirrored (u -> -u) onto the right one, so the skin stays symmetric."""
    n = len(params)
    ids = np.arange(n)
    return opening.smooth_opening(
        params,
        faces,
        _near_eye(1.0, verts[:n]),
        _surface,
        lambda p: _hole_coords(1.0, p),
        steps=np.array([1e-4, 1e-6]),  # finite-difference steps in z (mm) and u (rad)
        mirror=((ids // nu) * nu + (nu - ids % nu) % nu, np.array([1.0, -1.0])),
    )


def skin() -> tuple[F64, I64, F64]:
    v, f, c = _skin()
    return v.copy(), f.copy(), c.copy()


# --- rigid parts (built in design coordinates, shifted by OFFSET) -----------------------------------------


def _out(v: F64, f: I64) -> tuple[F64, I64]:
    import trimesh

    if trimesh.Trimesh(v, f, process=False).volume < 0:
        f = f[:, ::-1].copy()
    return v + OFFSET, f


def _eye(side: float) -> F64:
    return np.array([side * _EYE_L[0], _EYE_L[1], _EYE_L[2]])


def _eye_rot(side: float) -> F64:
    """(3, 3): the eye's own frame (its +z = gaze at rest) in the head frame: a yaw out to its side."""
    a = np.radians(side * EYE_YAW_DEG)
    return np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])


def _in_eye_frame(side: float, v: F64) -> F64:
    """Points built around the origin looking along +z -> placed at the eye, looking along its gaze."""
    return np.asarray(v @ _eye_rot(side).T + _eye(side), dtype=np.float64)


def eyeball(side: float) -> tuple[F64, I64]:
    return _out(*mt.ellipsoid(tuple(_eye(side)), (EYE_RADIUS,) * 3, subdiv=3))


def iris(side: float) -> tuple[F64, I64]:
    v, f = mt.cap(np.zeros(3), EYE_RADIUS + 0.12, 34.0, n_ring=28, n_rad=4)
    return _in_eye_frame(side, v) + OFFSET, f


def pupil(side: float) -> tuple[F64, I64]:
    v, f = mt.cap(np.zeros(3), EYE_RADIUS + 0.25, 16.0, n_ring=20, n_rad=2)
    return _in_eye_frame(side, v) + OFFSET, f


def eyelid(side: float, upper: bool = True) -> tuple[F64, I64]:
    """Upper lid shell; it turns about the eye's own x axis (see the lid joints' axes in head.toml)."""
    o = np.zeros(3)
    beta = (22.0, 125.0) if upper else (-125.0, -28.0)
    outer = mt.sphere_patch(o, EYE_RADIUS + 2.2, beta, (-84.0, 84.0), 14, 24)
    inner = mt.sphere_patch(o, EYE_RADIUS + 0.8, beta, (-84.0, 84.0), 14, 24)
    return _out(*mt.shell_from_grids(_in_eye_frame(side, outer), _in_eye_frame(side, inner)))


def _eye_hole_loop(side: float) -> tuple[F64, F64]:
    """The skin's eye opening as an ordered closed loop: (k, 3) rim points and (k, 3) skin normals there
    (design coordinates, normals pointing out of the head)."""
    import trimesh

    v, f, _ = _skin()
    v = v - OFFSET
    local = (v - _eye(side)) @ _eye_rot(side)
    ids = opening.boundary_loop(f, _near_eye(side, v))
    # wind the loop counter-clockwise about the eye's gaze (same for both eyes after their own frame)
    ang = np.unwrap(np.arctan2(local[ids, 1], local[ids, 0]))
    if ang[-1] < ang[0]:
        ids = ids[::-1]
    normals = trimesh.Trimesh(v, f, process=False).vertex_normals[ids]
    return v[ids], np.asarray(normals, dtype=np.float64)


def eye_socket(side: float) -> tuple[F64, I64]:
    """A dark cup behind the eyeball, lofted from the skin's eye opening so no line of sight through the
    opening reaches the head's inside (or, through the other eye's opening, the background).

    The opening is deep on the muzzle side (its rim stands ~25 mm in front of the eye's centre there), so a
    cup behind the eye alone left a tunnel open to the inside (issue: a hole beside the eye in side view).
    A flange 1.5 mm under the skin, 1.5 mm out from the rim along the skin (hidden by it, so a little skin
    motion opens no gap; pushed out in the eye's plane instead, it poked through the skin where the skin
    is oblique, dark spikes round the opening) joins the wall, which starts on the rim itself and runs
    back to a ring of radius ``EYE_RADIUS + 4`` at the eye's equator; a back hemisphere closes it. Open at
    the front, so it is drawn from both sides."""
    if side < 0:  # the mirror of the left one, exactly (the skin's triangle diagonals are not mirrored)
        v, f = eye_socket(1.0)
        return mt.mirror_x(v, f)
    rim, nrm = _eye_hole_loop(side)
    rot, c = _eye_rot(side), _eye(side)
    loc = (rim - c) @ rot  # eye frame
    n_loc = nrm @ rot
    # away from the opening along the skin: across the rim (loop counter-clockwise about the gaze)
    tangent = np.roll(loc, -1, axis=0) - np.roll(loc, 1, axis=0)
    away = np.cross(tangent, n_loc)
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    lip = loc + 1.5 * away - 1.5 * n_loc  # outside the opening, under the skin
    phi = np.arctan2(loc[:, 1], loc[:, 0])
    r_cup = EYE_RADIUS + 4.0
    z0 = -1.0
    equator = np.stack([r_cup * np.cos(phi), r_cup * np.sin(phi), np.full(len(phi), z0)], 1)
    rows = [lip]  # a flange under the skin, then the wall from the rim itself (no slit at the skin's edge)
    for t in np.linspace(0.0, 1.0, 7):
        rows.append((1.0 - t) * loc + t * equator)
    for th in np.radians(np.linspace(90.0, 170.0, 9)[1:]):  # polar angle from the gaze: back to the pole
        rows.append(
            np.stack(
                [
                    r_cup * np.sin(th) * np.cos(phi),
                    r_cup * np.sin(th) * np.sin(phi),
                    np.full(len(phi), z0 + r_cup * np.cos(th)),
                ],
                1,
            )
        )
    grid = np.stack(rows)  # (rows, k, 3)
    nr, k, _ = grid.shape
    verts = np.concatenate([grid.reshape(-1, 3), [[0.0, 0.0, z0 - r_cup]]])
    faces = np.concatenate([mt.grid_faces(nr, k, periodic_u=True), mt.fan((nr - 1) * k + np.arange(k), nr * k)])
    return verts @ rot.T + c + OFFSET, np.asarray(faces, dtype=np.int64)


def skull() -> tuple[F64, I64]:
    return _out(*mt.ellipsoid((0.0, 118.0, -15.0), (50.0, 34.0, 52.0), subdiv=3))


def nose() -> tuple[F64, I64]:
    """The dark inside of the nostrils (a small body behind the nose pad's dips)."""
    return _out(*mt.merge(*(mt.ellipsoid((s * 8.0, 99.0, 150.0), (3.5, 2.5, 3.0), subdiv=2) for s in (1.0, -1.0))))


def mouth_cavity() -> tuple[F64, I64]:
    return _out(*mt.ellipsoid((0.0, 74.0, 100.0), (22.0, 11.0, 48.0), subdiv=3))


def _mouth_path(inset_mm: float, z_back: float, spacing_mm: float) -> F64:
    """(k, 2) (x, z) points every ``spacing_mm`` along the mouth line, ``inset_mm`` inside the lips:
    up the right side, across the front, down the left side (design coordinates)."""
    z_front = _Z[-1] - inset_mm
    zs = np.linspace(z_back, z_front, 80)
    side = np.interp(zs, _Z, _W) - inset_mm
    x_front = float(side[-1])
    right = np.stack([-side, zs], 1)
    front = np.stack([np.linspace(-x_front, x_front, 20)[1:-1], np.full(18, z_front)], 1)
    left = np.stack([side, zs], 1)[::-1]
    line = np.concatenate([right, front, left])
    seg = np.linalg.norm(np.diff(line, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = int(s[-1] // spacing_mm) + 1
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, line[:, 0]), np.interp(t, s, line[:, 1])], 1)


def _tooth_row(y_gum: float, down: bool, inset_mm: float, canine_mm: float, canine_back_mm: float) -> tuple[F64, I64]:
    """Teeth along the mouth line; the two canines stand ``canine_back_mm`` behind the front."""
    pts = _mouth_path(inset_mm, 100.0, 4.2)
    z_front = _Z[-1] - inset_mm
    boxes = []
    canines = set()
    for sx in (1.0, -1.0):
        on_side = np.nonzero(np.sign(pts[:, 0]) == sx)[0]
        canines.add(int(on_side[np.argmin(np.abs(pts[on_side, 1] - (z_front - canine_back_mm)))]))
    for k, (x, z) in enumerate(pts):
        hgt = canine_mm if k in canines else 4.5
        lo_y, hi_y = (y_gum - hgt, y_gum) if down else (y_gum, y_gum + hgt)
        boxes.append(mt.box((x - 1.8, lo_y, z - 1.8), (x + 1.8, hi_y, z + 1.8)))
    return mt.merge(*boxes)


def teeth_upper() -> tuple[F64, I64]:
    return _out(*_tooth_row(83.0, True, 4.5, 10.0, 12.0))


def jaw() -> tuple[F64, I64]:
    teeth = _tooth_row(71.0, False, 9.0, 9.0, 20.0)
    t = np.linspace(-1.0, 1.0, 17)
    ang = t * np.pi / 2
    spine = np.stack([24.0 * np.sin(ang), 68.0 + 10.0 * np.abs(t) ** 2, 132.0 - 106.0 * (1 - np.cos(ang))], 1)
    bone = mt.tube_along(spine, np.full(len(spine), 3.2), 12)
    v, f = mt.merge(teeth, bone)
    return v + OFFSET, f


def tongue_root() -> tuple[F64, I64]:
    v, f = mt.ellipsoid((0.0, 74.5, 100.0), (13.0, 3.2, 20.0), subdiv=3)
    return _out(v, f)


def tongue_tip() -> tuple[F64, I64]:
    """Reaches to 4.7 mm behind the lower incisors at rest, so AU18 (tongue_extend -10) takes it past them."""
    v, f = mt.ellipsoid((0.0, 74.5, 132.5), (9.0, 2.8, 9.0), subdiv=3)
    return _out(v, f)


def neck() -> tuple[F64, I64]:
    pts = np.array([[0.0, 40.0, -55.0], [0.0, 10.0, -75.0], [0.0, -40.0, -105.0]])
    return _out(*mt.tube_along(pts, np.array([44.0, 44.0, 46.0]), 28))


def neck_collar() -> tuple[F64, I64]:
    """Visual only: the neck's top bent forward into the back of the head, so the head sits on its neck
    with no gap or ring (issue 11); fixed to the base like the neck, hidden inside the skin at the front."""
    top = np.array([0.0, 40.0, -55.0])  # the neck's top, continued along its own axis into the head
    axis = np.array([0.0, 30.0, 20.0]) / np.hypot(30.0, 20.0)
    pts = np.array([top - 4.0 * axis, top + 20.0 * axis, top + 44.0 * axis])
    return _out(*mt.tube_along(pts, np.array([44.0, 42.0, 36.0]), 28))


def ear(side: float) -> tuple[F64, I64]:
    """A cropped, erect ear: a tapered cup opening sideways-forward, base on the top of the skull."""
    nb, nt = 12, 14
    s = np.linspace(0.0, 1.0, nb)[:, None]  # base -> tip
    t = np.linspace(-1.0, 1.0, nt)[None, :]  # across the ear
    half = 24.0 * (1.0 - s) ** 0.9 + 1.5
    along = s * 68.0
    across = t * half
    cup = 8.0 * (1.0 - t**2) * (1.0 - 0.6 * s)
    base = np.array([40.0, 146.0, -12.0])
    up = np.array([0.35, 0.93, -0.1])
    up /= np.linalg.norm(up)
    fwd = np.array([1.0, 0.0, 0.15])  # across the ear: the broad side faces forward
    fwd -= up * (fwd @ up)
    fwd /= np.linalg.norm(fwd)
    out = np.cross(up, fwd)  # faces +x for the left ear
    mid = base + along[..., None] * up + across[..., None] * fwd
    outer = mid - (cup[..., None] - 1.3) * out
    inner = mid - (cup[..., None] + 1.3) * out
    v, f = mt.shell_from_grids(outer, inner)
    if side < 0:
        v, f = mt.mirror_x(v, f)
    return _out(v, f)


EAR_BASE_L = tuple(float(v) for v in np.array([40.0, 146.0, -12.0]) + OFFSET)
TONGUE_ROOT_PIVOT = tuple(float(v) for v in np.array([0.0, -30.0, 230.0]) + OFFSET)  # tongue_extend (remote)
TONGUE_TIP_PIVOT = tuple(float(v) for v in np.array([0.0, 74.5, 121.0]) + OFFSET)
