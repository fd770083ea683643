"""A triangle mesh of the cell's interior in the meridian half-plane, from its outline.

The domain (upper half, z ≥ 0, by mirror symmetry) is bounded by the axis
r = 0, the mid-plane z = 0 and the shell's meridian: a polyline from the pole
(0, z_p) on the axis to the equator (R, 0) on the mid-plane, given node by node
(`solver.fast.lagrangian` order). Every polyline node is a mesh vertex and every
polyline segment a mesh edge, so the mesh's boundary *is* the shell polygon:
a field that is linear on each segment (the shell's own interpolation) has
exactly the polygon's volume flux.

Target element size (µm) at a point x, from the polyline nodes b_k with local
spacing s_k:

    h(x) = min(h_max, min_k (s_k + g |x - b_k|)),      g = GRADING,

so the mesh is as fine as the shell at its boundary (down to ~0.01 µm at the
contact line) and coarsens away from it. Axis and mid-plane nodes march from
the polyline's ends by steps h(x); the interior points are taken from a
hierarchy of hexagonal lattices of spacing h_max/2^L (at each point the
lattice with spacing in (h/2, h]), at least 0.6 h from the boundary, and
joined by Delaunay triangulation (the domain is convex, so the triangulation
of the points covers exactly it; the edges along the polyline are checked).
"""

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from matplotlib.path import Path
from scipy.spatial import Delaunay

from common.errors import SolverError

GRADING = 0.25     # growth of the element size per µm away from the shell
MARGIN = 0.6       # interior points keep at least MARGIN h(x) from the boundary


def _spacing(r, z):
    """Local node spacing s_k of the polyline: the mean of the adjacent segments."""
    ds = np.hypot(np.diff(r), np.diff(z))
    return np.concatenate([[ds[0]], 0.5 * (ds[1:] + ds[:-1]), [ds[-1]]])


def size_function(r: npt.NDArray[np.float64], z: npt.NDArray[np.float64], h_max: float) -> Callable[[npt.ArrayLike], npt.NDArray[np.float64]]:
    """h(x) of the module docstring for points x (..., 2)."""
    b, s = np.column_stack([r, z]), _spacing(r, z)

    def h(x):
        x = np.asarray(x, float).reshape(-1, 2)
        out = np.empty(len(x))
        for i in range(0, len(x), 4096):
            d = np.linalg.norm(x[i: i + 4096, None, :] - b[None, :, :], axis=-1)
            out[i: i + 4096] = np.min(s[None, :] + GRADING * d, axis=1)
        return np.minimum(out, h_max)
    return h


def _distance_to_polyline(pts, r, z):
    """Distance of points (n, 2) to the polyline (r, z), by segments."""
    a = np.column_stack([r[:-1], z[:-1]])
    d = np.column_stack([np.diff(r), np.diff(z)])
    out = np.empty(len(pts))
    for i in range(0, len(pts), 2048):
        x = pts[i: i + 2048, None, :] - a[None]
        t = np.clip(np.sum(x * d, -1) / np.sum(d * d, -1), 0.0, 1.0)
        out[i: i + 2048] = np.min(np.linalg.norm(x - t[..., None] * d, axis=-1), axis=1)
    return out


def _march(start, end, h):
    """Nodes strictly between `start` and `end` (2-vectors) at steps h(x); a
    last gap shorter than half a step is closed by dropping the last node."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length, t, ts = np.linalg.norm(end - start), 0.0, []
    while True:
        t += float(h(start + (end - start) * t / length)[0])
        if t >= length:
            break
        ts.append(t)
    if ts and length - ts[-1] < 0.5 * float(h(end)[0]):
        ts.pop()
    return start + np.outer(np.asarray(ts) / length, end - start)


def _lattice(index, s):
    """Points (n, 2) of the hexagonal lattice of spacing s at integer indices
    (i, j) (n, 2), slightly jittered by a fixed function of the index (no four
    points on a circle, so the Delaunay triangulation is unique)."""
    i, j = index[:, 0], index[:, 1]
    x = (i + 0.5 * (j % 2)) * s
    y = j * s * np.sqrt(3) / 2
    jitter = 0.02 * s * np.stack([np.sin(12.9898 * i + 78.233 * j), np.cos(39.3468 * i + 11.135 * j)], 1)
    return np.column_stack([x, y]) + jitter


def _around(points, radius, s):
    """Indices of the lattice of spacing s within `radius` (box) of each point, deduplicated."""
    if len(points) == 0:
        return np.zeros((0, 2), int)
    m = int(np.ceil(radius / s)) + 1
    j0 = np.round(points[:, 1] / (s * np.sqrt(3) / 2)).astype(int)
    i0 = np.round(points[:, 0] / s).astype(int)
    di, dj = np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1))
    index = np.stack([(i0[:, None] + di.ravel()).ravel(), (j0[:, None] + dj.ravel()).ravel()], 1)
    return np.unique(index, axis=0)


def mesh_points(r: npt.ArrayLike, z: npt.ArrayLike, h_max: float = 0.5) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Vertices (n, 2) and triangles (m, 3) of the interior of the outline (r, z);
    the first len(r) vertices are the outline's nodes, in order."""
    r, z = np.asarray(r, float), np.asarray(z, float)
    if not (r[0] == 0 and z[-1] == 0 and z[0] > 0 and r[-1] > 0):
        raise SolverError("the outline must run from the pole (0, z_p) to the equator (R, 0)")
    h = size_function(r, z, h_max)
    axis = _march((0.0, z[0]), (0.0, 0.0), h)[::-1]
    mid = _march((r[-1], 0.0), (0.0, 0.0), h)[::-1]
    boundary = np.vstack([np.column_stack([r, z]), mid[::-1], [[0.0, 0.0]], axis])
    polygon = Path(boundary)
    s_min = float(h(boundary).min())
    levels = int(np.ceil(np.log2(h_max / s_min))) + 1
    interior, coarse = [], None
    for level in range(levels):
        s = h_max / 2**level
        if level == 0:
            index = _around(np.array([[0.5 * r.max(), 0.5 * z.max()]]), max(r.max(), z.max()), s)
        else:                     # refine only around the points that were too coarse
            index = _around(coarse, 2.0 * s, s)
        pts = _lattice(index, s)
        pts = pts[(pts[:, 0] > 0) & (pts[:, 1] > 0)]
        pts = pts[polygon.contains_points(pts)]
        hx = h(pts)
        coarse = pts[hx <= 0.5 * s]
        keep = (hx <= s * (1 + 1e-9)) & ((hx > 0.5 * s) | (level == levels - 1))
        pts, hx = pts[keep], hx[keep]
        dist = np.minimum(_distance_to_polyline(pts, r, z), np.minimum(pts[:, 0], pts[:, 1]))
        interior.append(pts[dist > MARGIN * hx])
    vertices = np.vstack([boundary] + interior)
    tri = Delaunay(vertices).simplices
    a, b, c = (vertices[tri[:, i]] for i in range(3))
    area = 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    centroid = (a + b + c) / 3.0
    good = (np.abs(area) > 1e-12 * h_max**2) & polygon.contains_points(centroid)
    tri = tri[good]
    tri[area[good] < 0] = tri[area[good] < 0][:, [0, 2, 1]]
    _check_outline(tri, len(r))
    return vertices, tri


def _check_outline(tri, n):
    """Every outline segment (k, k+1) must be an edge of the triangulation."""
    edges = np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    have = set(map(tuple, edges[edges[:, 1] < n]))
    missing = [k for k in range(n - 1) if (k, k + 1) not in have]
    if missing:
        raise SolverError(f"the interior mesh misses {len(missing)} outline segments "
                          f"(first at node {missing[0]}): is the outline convex?")
