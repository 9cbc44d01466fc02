"""Procedural meshes of the built-in ``human`` head (deterministic, numpy only; no downloaded assets).

The skin is a loft of horizontal superellipse cross-sections (neck up to a pole on the crown) with the
face carved in as depth bumps; it has two eye openings and a mouth slit (upper and lower lip share their
rest positions but not their faces, so the lower lip follows the jaw and the mouth opens). The eye
openings' rims are laid on their ellipses on the skin surface itself (`servoface.sim.heads.opening`), so
the skin's edge round each eye is a smooth curve, not a grid's stair-step. Rigid parts
(skull, jaw with lower teeth, upper teeth, eyeballs with iris and pupil, eyelid shells, neck, ears, the
dark mouth cavity and eye sockets) are placed around it. Head frame: mm, +y up, +z out of the face,
+x to the head's own left; the origin is the top of the neck.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from servoface.sim.heads import mesh_tools as mt
from servoface.sim.heads import opening
from servoface.sim.heads.mesh_tools import F64, I64

# --- the numbers head.toml refers to (keep in sync; tests check) -------------------------------------------
EYE_CENTRE_L = (32.0, 126.0, 66.0)
EYE_RADIUS = 12.0
EYE_HOLE_SEMI = (14.5, 8.5)  # skin eye opening, x and y half-sizes
MOUTH_Y = 72.0
MOUTH_HALF_WIDTH = 24.0
JAW_PIVOT = (0.0, 100.0, 5.0)

SKIN_RGBA = (0.87, 0.69, 0.58, 1.0)
LIP_RGBA = (0.72, 0.38, 0.38, 1.0)
BROW_RGBA = (0.33, 0.23, 0.17, 1.0)
NOSTRIL_RGBA = (0.35, 0.18, 0.15, 1.0)


def _upper_profile(y: F64) -> tuple[F64, F64, F64]:
    """Half-width W, front depth Df, back depth Db of the cross-section at height y (mm)."""
    ys = np.array([18, 30, 40, 52, 72, 95, 120, 150])
    w = np.array([44, 52, 58, 63, 67, 71, 75, 77])
    df = np.array([42, 60, 76, 80, 84, 88, 88, 84])
    db = np.array([50, 54, 60, 70, 84, 94, 100, 101])
    lo_w, lo_df, lo_db = np.interp(y, ys, w), np.interp(y, ys, df), np.interp(y, ys, db)
    s = np.clip((y - 150.0) / 86.0, 0.0, 1.0)
    f = np.sqrt(np.clip(1.0 - s * s, 0.0, 1.0))
    up = y > 150.0
    wv = np.where(up, 77.0 * f, lo_w)
    dfv = np.where(up, 84.0 * f * (1.0 - 0.12 * s), lo_df)
    dbv = np.where(up, 101.0 * f, lo_db)
    return wv, dfv, dbv


def _rows(nv: int) -> F64:
    """Row heights: denser over the face, one row exactly on the mouth line."""
    y = np.linspace(18.0, 235.999, 4000)
    w, df, _ = _upper_profile(y)
    ds = np.hypot(np.diff(y), np.abs(np.diff(w)) + np.abs(np.diff(df))) * 0.5
    dens = 1.0 + 1.3 * mt.smoothstep((y[1:] - 28.0) / 10.0) * mt.smoothstep((152.0 - y[1:]) / 10.0)
    s = np.concatenate([[0.0], np.cumsum(ds * dens)])
    rows = np.interp(np.linspace(0.0, s[-1], nv + 1)[:-1], s, y)
    k = int(np.argmin(np.abs(rows - MOUTH_Y)))
    rows[k] = MOUTH_Y
    return rows


def _columns(nu: int) -> F64:
    """Azimuth of each column (rad), 0 = front, denser at the front."""
    s = (np.arange(nu) - nu // 2) * (2.0 / nu)  # exactly odd about the front column
    k = 1.2
    return np.asarray(np.pi * (s + k * s**3) / (1.0 + k), dtype=np.float64)


def _face_depth(x: F64, y: F64) -> F64:
    """Extra depth (mm, +z) of the face features at head-frame (x, y)."""
    ax = np.abs(x)
    ex, ey = EYE_CENTRE_L[0], EYE_CENTRE_L[1]
    g = mt.gauss2
    dz = -8.0 * g(ax - ex, y - ey, 14.0, 10.0)  # eye sockets
    dz += 5.5 * g(ax - ex + 2.0, y - (ey + 19.0), 19.0, 5.0)  # brow ridge
    dz += 3.0 * g(x, y - 140.0, 9.0, 9.0)  # glabella
    # nose: a ridge that grows from the bridge to the tip, with a rounded underside
    t = np.clip((140.0 - y) / 42.0, 0.0, 1.0)
    amp = (3.0 + 19.0 * t**1.4) * mt.smoothstep((y - 86.0) / 11.0) * mt.smoothstep((148.0 - y) / 10.0)
    sig = 5.5 + 5.0 * t
    dz += amp * np.exp(-0.5 * (x / sig) ** 2)
    dz += 5.0 * g(x, y - 99.0, 7.0, 6.0)  # tip
    dz += 7.0 * g(ax - 12.5, y - 93.0, 5.0, 5.0)  # alae
    dz -= 4.0 * g(ax - 7.0, y - 89.5, 2.6, 1.8)  # nostrils
    dz += 4.0 * g(ax - 44.0, y - 106.0, 15.0, 12.0)  # cheekbones
    dz += 2.5 * g(ax - 28.0, y - 84.0, 9.0, 10.0)  # nasolabial fold
    dz += 2.5 * g(x, y - 84.0, 5.0, 4.0)  # philtrum
    dz += 6.0 * g(x, y - (MOUTH_Y + 4.0), 18.0, 3.8) * mt.smoothstep((y - MOUTH_Y + 1.0) / 2.0)  # upper lip
    dz += 5.5 * g(x, y - (MOUTH_Y - 5.0), 16.0, 4.2) * mt.smoothstep((MOUTH_Y + 1.0 - y) / 2.0)  # lower lip
    dz -= 2.5 * g(ax - MOUTH_HALF_WIDTH - 1.0, y - MOUTH_Y, 4.0, 5.0)  # mouth corners
    dz -= 2.5 * g(x, y - (MOUTH_Y - 15.0), 14.0, 3.5)  # mentolabial sulcus
    dz += 6.0 * g(x, y - 44.0, 15.0, 8.0)  # chin
    return np.asarray(dz, dtype=np.float64)


def _lip_weight(x: F64, y: F64) -> F64:
    up = mt.smoothstep((MOUTH_Y + 8.5 - y) / 2.0) * (y >= MOUTH_Y - 0.01)
    lo = mt.smoothstep((y - (MOUTH_Y - 10.0)) / 2.0) * (y <= MOUTH_Y + 0.01)
    half = MOUTH_HALF_WIDTH + 1.0 - 0.35 * np.abs(y - MOUTH_Y)
    side = mt.smoothstep((half - np.abs(x)) / 3.0)
    return np.asarray(np.maximum(up, lo) * side, dtype=np.float64)


def _brow_weight(x: F64, y: F64) -> F64:
    ax = np.abs(x)
    centre_y = EYE_CENTRE_L[1] + 21.0 - 0.004 * (ax - 30.0) ** 2
    band = mt.smoothstep((3.2 - np.abs(y - centre_y)) / 1.5)
    span = mt.smoothstep((ax - 10.0) / 3.0) * mt.smoothstep((52.0 - ax) / 4.0)
    return np.asarray(band * span, dtype=np.float64)


def _surface(y: F64, alpha: F64) -> F64:
    """(..., 3) skin points at height ``y`` (mm) and azimuth ``alpha`` (rad round the head, 0 = front, +pi/2 =
    the head's left); arrays of one shape. The skin is this surface on a grid of rows and columns, so a vertex
    moved in (y, alpha) stays on it."""
    y = np.asarray(y, dtype=np.float64)
    alpha = np.asarray(alpha, dtype=np.float64)
    w, df, db = _upper_profile(y)
    sa, ca = np.sin(alpha), np.cos(alpha)
    e = 0.9  # superellipse exponent (< 1: squarer cross-section)
    x = w * np.sign(sa) * np.abs(sa) ** e
    depth = np.where(ca >= 0, df, db)
    z = depth * np.sign(ca) * np.abs(ca) ** e
    front = mt.smoothstep((ca - 0.15) / 0.45)
    z = z + _face_depth(x, y) * front
    return np.stack([x, y, z], -1)


@lru_cache(maxsize=1)
def _skin() -> tuple[F64, I64, F64, dict[str, int]]:
    """(vertices, faces, vertex colours (n, 4), named vertex ids)."""
    nv, nu = 54, 96
    grid_y, grid_a = np.broadcast_arrays(_rows(nv)[:, None], _columns(nu)[None, :])
    rows = grid_y[:, 0]
    verts = _surface(grid_y, grid_a).reshape(-1, 3)
    faces = mt.grid_faces(nv, nu, periodic_u=True)
    n_grid = len(faces)
    pole = len(verts)
    verts = np.concatenate([verts, [[0.0, 236.0, -6.0]]])
    faces = np.concatenate([faces, mt.fan((nv - 1) * nu + np.arange(nu), pole)])
    # outward winding: check against the head centre and flip if needed
    tri = verts[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    if float(np.sum(n * (tri.mean(1) - np.array([0.0, 120.0, 0.0])))) < 0:
        faces = faces[:, ::-1].copy()

    # eye openings: drop the grid quads whose centre lies in the ellipse (per quad, so both sides match),
    # then lay the stair-step rim this leaves on the ellipse, on the skin surface (`_smooth_eye_rims`)
    cen = mt.quad_centres(verts, faces, n_grid)
    hole = np.zeros(len(faces), dtype=bool)
    for sx in (1.0, -1.0):
        r = np.sum(_hole_coords(sx, cen) ** 2, axis=1)
        hole |= (r < 1.0) & (cen[:, 2] > 20.0)
    faces = opening.swap_ear_diagonals(faces, n_grid, ~hole)[~hole]
    params = np.stack([grid_y, grid_a], -1).reshape(-1, 2)
    verts[:pole] = _surface(*_smooth_eye_rims(verts[:pole], faces, params, nu).T)

    # mouth slit on the mouth row: faces below it get their own copies of the lip-line vertices
    k = int(np.argmin(np.abs(rows - MOUTH_Y)))
    row_ids = k * nu + np.arange(nu)
    slit = row_ids[(np.abs(verts[row_ids, 0]) < MOUTH_HALF_WIDTH) & (verts[row_ids, 2] > 40.0)]
    below = np.all(verts[faces][:, :, 1] <= MOUTH_Y + 1e-6, axis=1) & np.isin(faces, slit).any(1)
    weights = _colour_weights(verts, faces)
    # the lower lip's copies of the lip-line vertices take their colour weights too
    verts, faces, copies = mt.split_vertices(verts, faces, slit, below)
    weights = np.concatenate([weights, weights[slit]])

    verts, faces, (kept,) = mt.compact(verts, faces, weights)
    weights = np.asarray(kept, dtype=np.float64)
    colours = np.tile(np.array(SKIN_RGBA), (len(verts), 1))
    for k, rgba in enumerate((NOSTRIL_RGBA, LIP_RGBA, BROW_RGBA)):
        wgt = weights[:, k]
        colours = colours * (1.0 - wgt[:, None]) + np.array(rgba) * wgt[:, None]
    named: dict[str, int] = {}
    return verts, faces, colours, named


_LIP_BLEND_ROUNDS = 3  # passes of `mt.blend_vertex_values` over the lips' colour weight
_LIP_GAIN = 1.3  # the lips' blended weight is scaled by this (then capped at 1)


def _colour_weights(verts: F64, faces: I64) -> F64:
    """(n, 3) weights of the nostril, lip and brow colours at the skin's vertices, on the uncut skin.

    The lips' edges ramp over 2..3 mm, sharper than the skin's grid is fine there (rows 4 mm apart, columns
    2.5 mm), so coloured per vertex their ends were drawn along the grid's triangles: a slanted, notched
    end on each lip, different left and right (session 36). The lips' weight is blended over the grid's
    edges, so its edge spans a couple of grid cells and is drawn as a smooth curve; a gain brings the full
    colour back inside the band."""
    x, y = verts[:, 0], verts[:, 1]
    front = verts[:, 2] > 30.0
    nostril = 0.85 * mt.gauss2(np.abs(x) - 7.0, y - 89.5, 2.4, 1.6)
    lips = mt.blend_vertex_values((_lip_weight(x, y) * front)[:, None], faces, _LIP_BLEND_ROUNDS)[:, 0]
    lips = np.minimum(lips * _LIP_GAIN, 1.0)
    return np.stack([nostril, lips, _brow_weight(x, y)], 1) * front[:, None]


def _hole_coords(side: float, points: F64) -> F64:
    """(..., 2) coordinates of points (..., 3) in which an eye's skin opening is the unit circle: the
    opening is an ellipse seen from the front (along -z), of half-sizes ``EYE_HOLE_SEMI``."""
    centre = np.array([side * EYE_CENTRE_L[0], EYE_CENTRE_L[1]])
    return np.asarray((points[..., :2] - centre) / np.array(EYE_HOLE_SEMI), dtype=np.float64)


def _near_eye(side: float, points: F64) -> NDArray[np.bool_]:
    """(n,) points (n, 3) round an eye's opening on the face (not the back of the head)."""
    d = np.abs(points[:, :2] - np.array([side * EYE_CENTRE_L[0], EYE_CENTRE_L[1]]))
    return np.asarray((d[:, 0] < 25.0) & (d[:, 1] < 20.0) & (points[:, 2] > 20.0))


def _smooth_eye_rims(verts: F64, faces: I64, params: F64, nu: int) -> F64:
    """New (y, azimuth) params (n, 2) of the grid vertices (n = rows x nu): the left eye's opening smoothed
    (`opening.smooth_opening`) and mirrored (azimuth -> -azimuth) onto the right one, so the skin stays
    symmetric."""
    ids = np.arange(len(params))
    return opening.smooth_opening(
        params,
        faces,
        _near_eye(1.0, verts),
        _surface,
        lambda p: _hole_coords(1.0, p),
        steps=np.array([1e-4, 1e-6]),  # finite-difference steps in y (mm) and azimuth (rad)
        mirror=((ids // nu) * nu + (nu - ids % nu) % nu, np.array([1.0, -1.0])),
    )


def skin() -> tuple[F64, I64, F64]:
    v, f, c, _ = _skin()
    return v.copy(), f.copy(), c.copy()


# --- rigid parts -------------------------------------------------------------------------------------------


def eyeball(side: float) -> tuple[F64, I64]:
    c = (side * EYE_CENTRE_L[0], EYE_CENTRE_L[1], EYE_CENTRE_L[2])
    return mt.ellipsoid(c, (EYE_RADIUS,) * 3, subdiv=3)


def iris(side: float) -> tuple[F64, I64]:
    c = np.array([side * EYE_CENTRE_L[0], EYE_CENTRE_L[1], EYE_CENTRE_L[2]])
    return mt.cap(c, EYE_RADIUS + 0.12, 25.0, n_ring=28, n_rad=4)


def pupil(side: float) -> tuple[F64, I64]:
    c = np.array([side * EYE_CENTRE_L[0], EYE_CENTRE_L[1], EYE_CENTRE_L[2]])
    return mt.cap(c, EYE_RADIUS + 0.25, 10.5, n_ring=20, n_rad=2)


def eyelid(side: float, upper: bool) -> tuple[F64, I64]:
    """A thin spherical shell over the eyeball; its edge is the lid margin (arched, rotates about x)."""
    c = np.array([side * EYE_CENTRE_L[0], EYE_CENTRE_L[1], EYE_CENTRE_L[2]])
    beta = (16.0, 125.0) if upper else (-125.0, -24.0)
    r_in, r_out = (1.7, 2.8) if upper else (0.6, 1.5)  # the upper lid closes over the lower one
    outer = mt.sphere_patch(c, EYE_RADIUS + r_out, beta, (-84.0, 84.0), 14, 24)
    inner = mt.sphere_patch(c, EYE_RADIUS + r_in, beta, (-84.0, 84.0), 14, 24)
    v, f = mt.shell_from_grids(outer, inner)
    return _outward(v, f)


def lid_line(side: float, upper: bool, crease: bool = False) -> tuple[F64, I64]:
    """A thin tube along a lid: the lash line on the margin, or (``crease``) the upper lid's crease.

    Visual only: a closed lid reads as a lid (a dark margin and a fold above it), not as a skin bulb."""
    c = np.array([side * EYE_CENTRE_L[0], EYE_CENTRE_L[1], EYE_CENTRE_L[2]])
    if crease:
        beta, r_mm, thick_mm, psi = 40.0, EYE_RADIUS + 2.75, 0.45, 70.0
    elif upper:
        beta, r_mm, thick_mm, psi = 16.6, EYE_RADIUS + 2.5, 1.1, 80.0
    else:
        beta, r_mm, thick_mm, psi = -24.6, EYE_RADIUS + 1.2, 0.45, 78.0
    spine = mt.sphere_patch(c, r_mm, (beta, beta), (-psi, psi), 1, 25)[0]
    taper = thick_mm * (0.45 + 0.55 * np.cos(np.linspace(-1.2, 1.2, len(spine))))
    return mt.tube_along(spine, taper, 8)


def _outward(v: F64, f: I64) -> tuple[F64, I64]:
    import trimesh

    if trimesh.Trimesh(v, f, process=False).volume < 0:
        f = f[:, ::-1].copy()
    return v, f


def eye_socket(side: float) -> tuple[F64, I64]:
    """A dark cup behind the eyeball so the gap around it reads as shadow, not as the head's inside."""
    c = np.array([side * EYE_CENTRE_L[0], EYE_CENTRE_L[1], EYE_CENTRE_L[2] - 1.0])
    flip = np.array([-1.0, 1.0, -1.0])  # front hemisphere patch turned 180 deg about y -> back cup
    outer = c + (mt.sphere_patch(c, EYE_RADIUS + 4.0, (-89.0, 89.0), (-89.0, 89.0), 16, 16) - c) * flip
    inner = c + (mt.sphere_patch(c, EYE_RADIUS + 3.2, (-89.0, 89.0), (-89.0, 89.0), 16, 16) - c) * flip
    return _outward(*mt.shell_from_grids(outer, inner))


def skull() -> tuple[F64, I64]:
    return mt.ellipsoid((0.0, 152.0, -14.0), (64.0, 74.0, 72.0), subdiv=3)


def mouth_cavity() -> tuple[F64, I64]:
    """A dark cup open towards the lips: what shows between the teeth when the mouth opens.

    Its rim sits 6+ mm behind the skin at the mouth corners, so a corner pulled back (AU20, AU14) does
    not uncover it (the dark crease lines of issue 11)."""
    c = np.array([0.0, 68.0, 68.0])
    flip = np.array([-1.0, 1.0, -1.0])
    outer = mt.sphere_patch(np.zeros(3), 1.0, (-89.0, 89.0), (-89.0, 89.0), 18, 18) * flip
    semi = np.array([25.0, 23.0, 36.0])
    return _outward(*mt.shell_from_grids(c + outer * (semi + 1.0), c + outer * semi))


def _arch(y: float, z_front: float, half_w: float, depth: float, n: int = 15) -> F64:
    t = np.linspace(-1.0, 1.0, n)
    return np.stack([half_w * np.sin(t * 1.25), np.full(n, y), z_front - depth * (1 - np.cos(t * 1.25))], 1)


def _teeth(y: float, height: float, z_front: float) -> tuple[F64, I64]:
    pts = _arch(y, z_front, 21.0, 16.0)
    parts = []
    for p in pts:
        lo = (p[0] - 2.0, p[1] - height / 2, p[2] - 2.6)
        hi = (p[0] + 2.0, p[1] + height / 2, p[2] + 1.2)
        parts.append(mt.box(lo, hi))
    return mt.merge(*parts)


def teeth_upper() -> tuple[F64, I64]:
    return _teeth(MOUTH_Y + 2.6, 7.5, 80.0)  # incisal edge 1.2 mm below the lip line: they show when the lips part


def jaw() -> tuple[F64, I64]:
    """Lower teeth on a U-shaped mandible, inside the skin."""
    teeth = _teeth(MOUTH_Y - 5.6, 7.0, 79.5)
    t = np.linspace(-1.0, 1.0, 17)
    spine = np.stack([40.0 * np.sin(t * 1.35), 56.0 + 14.0 * np.abs(t) ** 2, 74.0 - 62.0 * (1 - np.cos(t * 1.35))], 1)
    bone = mt.tube_along(spine, np.full(len(spine), 5.0), 12)
    return mt.merge(teeth, bone)


def neck() -> tuple[F64, I64]:
    import trimesh

    c = trimesh.creation.cylinder(radius=40.0, height=120.0, sections=32)
    v = np.asarray(c.vertices) @ np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], dtype=np.float64) + [
        0.0,
        -28.0,
        -4.0,
    ]
    return v, np.asarray(c.faces, dtype=np.int64)


def ear(side: float) -> tuple[F64, I64]:
    """A flat-ish rounded ear shell on the side of the head."""
    nb, nt = 10, 16
    t = np.linspace(-np.pi / 2, np.pi / 2, nt)[None, :]
    r = np.linspace(0.2, 1.0, nb)[:, None]
    zz = 14.0 * r * np.cos(t) - 4.0
    yy = 105.0 + 28.0 * r * np.sin(t) + 4.0
    cup = 2.5 * (1 - r) ** 2
    x_out = 75.0 + 6.0 * r + 3.0 * r * np.cos(t) - cup
    outer = np.stack([x_out + 1.6, yy, zz], -1)
    inner = np.stack([x_out - 1.6, yy, zz], -1)
    v, f = mt.shell_from_grids(outer, inner)
    v, f = _outward(v, f)
    if side < 0:
        v, f = mt.mirror_x(v, f)
    return v, f
