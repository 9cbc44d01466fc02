"""Small deterministic mesh builders for the procedural heads (grids, caps, shells, splits).

Everything here is plain numpy; results are turned into trimesh objects by the generators.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


def smoothstep(x: F64 | float) -> F64:
    """0 below 0, 1 above 1, C1-smooth in between."""
    t = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.asarray(t * t * (3.0 - 2.0 * t), dtype=np.float64)


def gauss2(dx: F64, dy: F64, sx: float, sy: float) -> F64:
    """Anisotropic 2-D gaussian bump, 1 at the centre."""
    return np.asarray(np.exp(-0.5 * ((dx / sx) ** 2 + (dy / sy) ** 2)), dtype=np.float64)


def grid_faces(nv: int, nu: int, periodic_u: bool) -> I64:
    """Triangles of an (nv, nu) vertex grid indexed ``j * nu + i`` (j = row, i = column).

    Faces are wound so that with rows going "up" and columns going "left to right seen from outside" the
    normals point outwards (callers flip with ``faces[:, ::-1]`` if needed).
    """
    cols = nu if periodic_u else nu - 1
    jj, ii = np.meshgrid(np.arange(nv - 1), np.arange(cols), indexing="ij")
    j = jj.ravel()
    i = ii.ravel()
    i1 = (i + 1) % nu
    a = j * nu + i
    b = j * nu + i1
    c = (j + 1) * nu + i1
    d = (j + 1) * nu + i
    tri = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    # interleave so faces of one quad stay adjacent (stable, deterministic order)
    n = len(a)
    order = np.arange(2 * n).reshape(2, n).T.ravel()
    return np.asarray(tri[order], dtype=np.int64)


def quad_corners(faces: I64, n_grid: int) -> I64:
    """(n_grid / 2, 4): the four distinct vertices of each grid quad (faces 2q and 2q + 1), any winding."""
    ids = np.sort(faces[:n_grid].reshape(-1, 6), axis=1)
    first = np.ones(ids.shape, dtype=bool)
    first[:, 1:] = ids[:, 1:] != ids[:, :-1]
    return np.asarray(ids[first].reshape(-1, 4), dtype=np.int64)


def quad_centres(vertices: F64, faces: I64, n_grid: int) -> F64:
    """Per face: the centre of its grid quad (faces 2q and 2q + 1 of ``grid_faces`` share quad q), so
    decisions taken on it are the same for both triangles and mirror-symmetric; faces past ``n_grid``
    (fans) use their own centroid."""
    cen = vertices[faces].mean(1)
    corners = quad_corners(faces, n_grid)
    q = np.sort(vertices[corners], axis=1).sum(1) / 4.0  # sorted: same summation order for mirror quads
    cen[:n_grid] = np.repeat(q, 2, axis=0)
    out: F64 = np.round(cen, 9)
    return out  # summation order differs between mirror quads; keep decisions identical


def blend_vertex_values(values: F64, faces: I64, rounds: int) -> F64:
    """Per-vertex values (n, k) moved ``rounds`` times halfway to the mean over their edge neighbours in
    ``faces`` (vertices on no face keep theirs): a value that steps from one vertex to the next is spread
    over a few edges, so interpolated over the triangles it changes along a smooth curve."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    e = np.concatenate([e, e[:, ::-1]])
    deg = np.bincount(e[:, 0], minlength=len(values)).astype(np.float64)[:, None]
    out = np.asarray(values, dtype=np.float64).copy()
    for _ in range(rounds):
        acc = np.zeros_like(out)
        np.add.at(acc, e[:, 0], out[e[:, 1]])
        out = np.where(deg > 0, 0.5 * out + 0.5 * acc / np.maximum(deg, 1.0), out)
    return out


def fan(ring: I64, centre: int, reverse: bool = False) -> I64:
    """Triangles joining a closed ring of vertex ids to one centre vertex."""
    nxt = np.roll(ring, -1)
    tri = np.stack([ring, nxt, np.full_like(ring, centre)], 1)
    return np.asarray(tri[:, ::-1] if reverse else tri, dtype=np.int64)


def split_vertices(vertices: F64, faces: I64, vertex_ids: I64, face_mask: NDArray[np.bool_]) -> tuple[F64, I64, I64]:
    """Duplicate ``vertex_ids``; faces in ``face_mask`` use the copies (cuts a slit such as a mouth).

    Returns (vertices, faces, copy_ids) with copy_ids[k] the new index of vertex_ids[k].
    """
    n = len(vertices)
    copy_ids = np.arange(n, n + len(vertex_ids), dtype=np.int64)
    remap = np.arange(n, dtype=np.int64)
    remap[vertex_ids] = copy_ids
    faces = faces.copy()
    faces[face_mask] = remap[faces[face_mask]]
    return np.concatenate([vertices, vertices[vertex_ids]]), faces, copy_ids


def compact(vertices: F64, faces: I64, *extra: NDArray[np.generic]) -> tuple[F64, I64, list[NDArray[np.generic]]]:
    """Drop unreferenced vertices (and the matching rows of ``extra`` per-vertex arrays)."""
    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    new_index = np.cumsum(used) - 1
    return vertices[used], np.asarray(new_index[faces], dtype=np.int64), [e[used] for e in extra]


def boundary_vertices(faces: I64) -> I64:
    """Vertex ids on open edges (edges used by exactly one face)."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    return np.asarray(np.unique(uniq[counts == 1].ravel()), dtype=np.int64)


def shell_from_grids(outer: F64, inner: F64) -> tuple[F64, I64]:
    """A closed thin shell from two (nv, nu, 3) grids of equal shape (outer and inner surface).

    Used for eyelids and ears: the open patch gets thickness so it renders and collides as a solid.
    """
    nv, nu, _ = outer.shape
    n = nv * nu
    f_out = grid_faces(nv, nu, periodic_u=False)
    f_in = grid_faces(nv, nu, periodic_u=False)[:, ::-1] + n
    ring = np.concatenate(
        [
            np.arange(nu),  # bottom row, left to right
            np.arange(1, nv) * nu + (nu - 1),  # right column, up
            (nv - 1) * nu + np.arange(nu - 2, -1, -1),  # top row, right to left
            np.arange(nv - 2, 0, -1) * nu,  # left column, down
        ]
    )
    a, b = ring, np.roll(ring, -1)
    side = np.concatenate([np.stack([b, a, a + n], 1), np.stack([b, a + n, b + n], 1)])
    verts = np.concatenate([outer.reshape(-1, 3), inner.reshape(-1, 3)])
    return verts, np.asarray(np.concatenate([f_out, f_in, side]), dtype=np.int64)


def ellipsoid(
    centre: tuple[float, float, float], semi_mm: tuple[float, float, float], subdiv: int = 3
) -> tuple[F64, I64]:
    """A closed ellipsoid (scaled icosphere), outward normals."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdiv, radius=1.0)
    v = np.asarray(s.vertices) * np.asarray(semi_mm) + np.asarray(centre)
    return v, np.asarray(s.faces, dtype=np.int64)


def sphere_patch(
    centre: F64,
    radius: float,
    beta_deg: tuple[float, float],
    psi_deg: tuple[float, float],
    nb: int,
    npsi: int,
) -> F64:
    """(nb, npsi, 3) points on a sphere, parameterised about the x axis (eyelid coordinates).

    beta = rotation about +x from the forward (+z) direction towards +y (up); psi = angle out of the y-z
    plane towards +x. Rows of constant beta are great circles through the x-axis poles, so a lid edge is
    arched when seen from the front and turning the lid about x just shifts beta.
    """
    b = np.radians(np.linspace(beta_deg[0], beta_deg[1], nb))[:, None]
    p = np.radians(np.linspace(psi_deg[0], psi_deg[1], npsi))[None, :]
    x = np.sin(p) * np.ones_like(b)
    y = np.cos(p) * np.sin(b)
    z = np.cos(p) * np.cos(b)
    return np.asarray(centre + radius * np.stack([x, y, z], -1), dtype=np.float64)


def cap(centre: F64, radius: float, half_angle_deg: float, n_ring: int = 24, n_rad: int = 5) -> tuple[F64, I64]:
    """An open spherical cap around +z (iris, pupil), outward normals."""
    rings = [np.array([[0.0, 0.0, 1.0]])]
    for k in range(1, n_rad + 1):
        t = np.radians(half_angle_deg) * k / n_rad
        a = np.linspace(0, 2 * np.pi, n_ring, endpoint=False)
        rings.append(np.stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.full_like(a, np.cos(t))], 1))
    v = np.concatenate(rings) * radius + centre
    faces = [fan(np.arange(1, n_ring + 1), 0, reverse=True)]
    for k in range(1, n_rad):
        base = 1 + (k - 1) * n_ring
        g = grid_faces(2, n_ring, periodic_u=True) + base
        faces.append(g)
    return v, np.asarray(np.concatenate(faces)[:, ::-1], dtype=np.int64)


def box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> tuple[F64, I64]:
    import trimesh

    b = trimesh.creation.box(bounds=np.array([lo, hi], dtype=np.float64))
    return np.asarray(b.vertices, dtype=np.float64), np.asarray(b.faces, dtype=np.int64)


def merge(*meshes: tuple[F64, I64]) -> tuple[F64, I64]:
    """Concatenate (vertices, faces) pairs into one vertex/face set."""
    vs, fs, off = [], [], 0
    for v, f in meshes:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    return np.concatenate(vs), np.asarray(np.concatenate(fs), dtype=np.int64)


def mirror_x(vertices: F64, faces: I64) -> tuple[F64, I64]:
    """Mirror a mesh across x = 0 (flips winding so normals stay outward)."""
    v = vertices.copy()
    v[:, 0] *= -1.0
    return v, faces[:, ::-1].copy()


def tube_along(points: F64, radius: F64, n_around: int = 16) -> tuple[F64, I64]:
    """A closed tube through a polyline of centre points (k, 3) with per-point radius (k,)."""
    k = len(points)
    tang = np.gradient(points, axis=0)
    tang /= np.linalg.norm(tang, axis=1, keepdims=True)
    up = np.array([0.0, 1.0, 0.0])
    rings = []
    for c, t, r in zip(points, tang, radius, strict=True):
        ref = up if abs(float(t @ up)) < 0.9 else np.array([1.0, 0.0, 0.0])
        a = np.cross(t, ref)
        a /= np.linalg.norm(a)
        b = np.cross(t, a)
        ang = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
        rings.append(c + r * (np.cos(ang)[:, None] * a + np.sin(ang)[:, None] * b))
    v = np.concatenate(rings + [points[:1], points[-1:]])
    f = grid_faces(k, n_around, periodic_u=True)
    start, end = len(v) - 2, len(v) - 1
    f = np.concatenate([f, fan(np.arange(n_around), start), fan((k - 1) * n_around + np.arange(n_around), end, True)])
    return v, np.asarray(f, dtype=np.int64)
