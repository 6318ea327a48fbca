"""Convex polygons: validation, normalisation (batched convex hull), bounds (SR-SAT-1, SR-SAT-4).

Layout: a batch of B point sets is two (P, B) arrays (point index leading, set index
trailing); polygons are :class:`~pipeline.types.ConvexPolygons`, (2, K, N) vertex-major. Every
reduction over the points of one set is then a whole-row numpy operation.

Numerics. Everything is double precision with explicit error allowances, so that each
"clear" verdict downstream is a proof in exact arithmetic on the given floats. ``U`` is the
unit roundoff; ``M`` is the largest coordinate magnitude of the points involved. An
orientation ``(w-u) x (p-u)`` computed in floating point is within ``ORIENT_ERR * |w-u| * M``
of its exact value (about 6u derived, 8u used). The hull inserts a point only when it lies
outside an edge by more than ``HULL_TAU * |e| * M`` (so it certainly lies outside), and a
point it leaves out is therefore within ``HULL_HALFPLANE * M`` of every edge's half-plane;
near a vertex of interior angle ``alpha`` that is at most ``HULL_HALFPLANE * M / sin(alpha/2)``
from the polygon. That bound is stored per polygon as ``slack_m`` (zero when every input
point is a vertex or certainly inside), and the collision check adds it to its clearance
threshold, so a collision with a point the hull left out by rounding is still reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.errors import DegeneratePolygonError, GeometryError, NonFiniteGeometryError
from pipeline.frames import to_parent
from pipeline.types import ConvexPolygons, FloatArray, IntArray

__all__ = [
    "HULL_HALFPLANE",
    "HULL_TAU",
    "MAX_COORD_M",
    "ORIENT_ERR",
    "DegeneratePolygonError",
    "GeometryError",
    "NonFiniteGeometryError",
    "PolygonBounds",
    "U",
    "Workspace",
    "convex_hull_batch",
    "convex_polygons",
    "no_polygons",
    "polygon_bounds",
    "polygons_from_hull",
    "transform_polygons",
]

U = 2.0**-53
ORIENT_ERR = 8.0 * U
HULL_TAU = 16.0 * U
HULL_HALFPLANE = HULL_TAU + ORIENT_ERR
# Coordinates beyond this are rejected: squares of edge vectors must not overflow, and no
# robot works 1000 km from its map origin.
MAX_COORD_M = 1.0e6
# A vertex sharper than this (sin of half its interior angle) cannot bound the hull's
# rounding slack usefully; such a polygon with points within rounding of its boundary is
# rejected rather than given a meaningless slack.
_MIN_SIN_HALF = 1.0e-9
_PREVIOUS_OF_4 = np.array([3, 0, 1, 2])  # the entry before each of four, cyclically


class Workspace:
    """Reusable scratch buffers, grown on demand, handed out as contiguous views.

    Large per-call temporaries would be fresh mmap'd pages each cycle (glibc maps blocks over
    128 KB), so the hot paths take their scratch from here. Not thread-safe: one per checker.
    """

    def __init__(self) -> None:
        self._buffers: dict[str, npt.NDArray[np.float64]] = {}

    def get(self, name: str, shape: tuple[int, ...]) -> Any:
        """A C-contiguous float64 array of ``shape`` backed by the buffer called ``name``."""
        size = 1
        for extent in shape:
            size *= extent
        buffer = self._buffers.get(name)
        if buffer is None or buffer.size < size:
            buffer = np.empty(max(size, 4096))
            self._buffers[name] = buffer
        return buffer[:size].reshape(shape)

    @property
    def nbytes(self) -> int:
        """Bytes held by all buffers."""
        return sum(b.nbytes for b in self._buffers.values())


def _check_points(px: FloatArray, py: FloatArray, what: str) -> None:
    finite = np.isfinite(px) & np.isfinite(py)
    if not finite.all():
        row, point = np.argwhere(~finite)[0]
        raise NonFiniteGeometryError(
            f"{what} {row}: point {point} is ({float(px[row, point])!r}, "
            f"{float(py[row, point])!r}); expected finite coordinates in metres"
        )
    big = (np.abs(px) > MAX_COORD_M) | (np.abs(py) > MAX_COORD_M)
    if big.any():
        row, point = np.argwhere(big)[0]
        raise NonFiniteGeometryError(
            f"{what} {row}: point {point} is ({float(px[row, point])!r}, "
            f"{float(py[row, point])!r}); expected coordinates within +/-{MAX_COORD_M:g} m"
        )


def _initial_vertices(xs: FloatArray, ys: FloatArray) -> tuple[IntArray, IntArray]:
    """Per set (row): the extreme points in -x, -y, +x, +y, counter-clockwise, deduplicated.

    Ties are broken towards a corner (lowest-x point: lowest y; lowest-y point: highest x;
    highest-x point: highest y; highest-y point: lowest x), so each is an exact hull vertex.
    Returns ``(order (B, 4), counts (B,))`` with unused slots repeating the first index.
    """
    n_sets = xs.shape[0]
    xmin = xs.min(axis=1, keepdims=True)
    xmax = xs.max(axis=1, keepdims=True)
    ymin = ys.min(axis=1, keepdims=True)
    ymax = ys.max(axis=1, keepdims=True)
    left = np.where(xs == xmin, ys, np.inf).argmin(axis=1)
    bottom = np.where(ys == ymin, xs, -np.inf).argmax(axis=1)
    right = np.where(xs == xmax, ys, -np.inf).argmax(axis=1)
    top = np.where(ys == ymax, xs, np.inf).argmin(axis=1)
    cand = np.empty((n_sets, 4), dtype=left.dtype)
    cand[:, 0], cand[:, 1], cand[:, 2], cand[:, 3] = left, bottom, right, top
    rows = np.arange(n_sets)[:, None]
    cx, cy = xs[rows, cand], ys[rows, cand]
    dup = (cx == cx[:, _PREVIOUS_OF_4]) & (cy == cy[:, _PREVIOUS_OF_4])
    dup[:, 0] = False  # the first entry (lowest x) always stays
    keep = ~dup
    # A later entry may equal the first one after wrapping round (e.g. top == left).
    dup_first = (cx == cx[:, :1]) & (cy == cy[:, :1])
    dup_first[:, 0] = False
    keep &= ~dup_first
    counts = keep.sum(axis=1)
    slot = np.cumsum(keep, axis=1) - 1
    order = np.repeat(left[:, None], 4, axis=1)
    r, c = np.nonzero(keep)
    order[r, slot[r, c]] = cand[r, c]
    return order, counts


def convex_hull_batch(
    px: npt.ArrayLike,
    py: npt.ArrayLike,
    *,
    what: str = "point set",
    workspace: Workspace | None = None,
) -> tuple[IntArray, IntArray, FloatArray]:
    """Convex hulls of B point sets given as (B, P) arrays of x and y in metres (SR-SAT-3).

    Returns ``(order, counts, slack_m)``: ``order`` (B, H) holds, per set, the indices of
    the hull vertices counter-clockwise starting at the lowest-x point, padded with the first
    index; ``counts`` (B,) the number of vertices; ``slack_m`` (B,) the rounding bound
    described in the module docstring. Vertices are input points; duplicate and collinear
    points are never vertices. A set may repeat points (padding) freely.

    Quickhull, vectorised over the sets: every round inserts, after each edge, the point
    farthest outside it, until no point is certainly outside any edge.

    Raises :class:`NonFiniteGeometryError` for a non-finite or huge coordinate and
    :class:`DegeneratePolygonError` when a set has fewer than 3 distinct, non-collinear points.
    """
    xs = np.ascontiguousarray(px, dtype=np.float64)
    ys = np.ascontiguousarray(py, dtype=np.float64)
    if xs.ndim != 2 or xs.shape != ys.shape or xs.shape[1] < 1:
        raise GeometryError(f"{what}: expected (B, P) arrays of equal shape, got {xs.shape}")
    _check_points(xs, ys, what)
    ws = workspace if workspace is not None else Workspace()
    n_sets, n_points = xs.shape
    magnitude = np.maximum(np.abs(xs).max(axis=1), np.abs(ys).max(axis=1))
    order, counts = _initial_vertices(xs, ys)
    alone = counts < 2
    if alone.any():
        bad = int(np.flatnonzero(alone)[0])
        raise DegeneratePolygonError(
            f"{what} {bad}: all points coincide at ({float(xs[bad, 0])!r}, "
            f"{float(ys[bad, 0])!r}); a polygon needs at least 3 distinct points"
        )
    # Working set: the points that may still become vertices, compacted per set; `index`
    # maps them back to input indices. Padding slots repeat the set's first vertex (a vertex
    # is never outside an edge) and are marked invalid.
    sets = np.arange(n_sets)[:, None]
    index: IntArray = np.broadcast_to(np.arange(n_points), (n_sets, n_points))
    valid = np.ones((n_sets, n_points), dtype=bool)
    wx, wy = xs, ys
    near_sets: list[IntArray] = []  # points dropped while within rounding of the boundary
    near_idx: list[IntArray] = []
    while True:
        rows = order.shape[1]
        nxt = np.concatenate((order[:, 1:], order[:, :1]), axis=1)
        ux, uy = xs[sets, order], ys[sets, order]
        ex, ey = xs[sets, nxt] - ux, ys[sets, nxt] - uy
        limit = HULL_TAU * np.sqrt(ex * ex + ey * ey) * magnitude[:, None]
        width = wx.shape[1]
        # cross[b, k, j] = e_k x (p_j - u_k): negative means p_j lies right of (outside) edge k
        cross = ws.get("hull_cross", (n_sets, rows, width))
        tmp = ws.get("hull_tmp", (n_sets, rows, width))
        np.subtract(wy[:, None, :], uy[:, :, None], out=cross)
        np.multiply(cross, ex[:, :, None], out=cross)
        np.subtract(wx[:, None, :], ux[:, :, None], out=tmp)
        np.multiply(tmp, ey[:, :, None], out=tmp)
        np.subtract(cross, tmp, out=cross)
        # A point outside no edge by more than the threshold can never become a vertex (the
        # polygon only grows); if it is not certainly inside either, remember it for slack.
        outside = (cross < -limit[:, :, None]).any(axis=1)
        near = (cross <= (ORIENT_ERR / HULL_TAU) * limit[:, :, None]).any(axis=1)
        r, c = np.nonzero(valid & ~outside & near)
        near_sets.append(r)
        near_idx.append(index[r, c])
        if not outside.any():
            break
        farthest = cross.argmin(axis=2)
        deepest = cross.min(axis=2)  # the value at `farthest`
        insert = deepest < -limit
        # Each edge with an outside point gets its farthest point inserted right after u.
        k = np.arange(rows)[None, :]
        before = np.cumsum(insert, axis=1) - insert
        new_counts = counts + insert.sum(axis=1)
        grown = np.repeat(order[:, :1], int(new_counts.max()), axis=1)
        r, c = np.nonzero(k < counts[:, None])
        grown[r, c + before[r, c]] = order[r, c]
        r, c = np.nonzero(insert)
        grown[r, c + before[r, c] + 1] = index[r, farthest[r, c]]
        order, counts = grown, new_counts
        # Keep the points still outside some edge, except the ones just made vertices.
        alive = valid & outside
        alive[r, farthest[r, c]] = False
        keep = int(alive.sum(axis=1).max())
        pick = np.argsort(~alive, axis=1, kind="stable")[:, :keep]
        valid = alive[sets, pick]
        index = np.where(valid, index[sets, pick], order[:, :1])
        wx, wy = xs[sets, index], ys[sets, index]
    flat = counts < 3
    if flat.any():
        bad = int(np.flatnonzero(flat)[0])
        raise DegeneratePolygonError(
            f"{what} {bad}: all points are collinear (within {HULL_HALFPLANE * magnitude[bad]:.3g}"
            " m); a polygon needs 3 points that are not on one line"
        )
    near = (np.concatenate(near_sets), np.concatenate(near_idx))
    slack = _hull_slack(xs, ys, order, counts, near, magnitude, what)
    return order, counts, slack


def _hull_slack(
    xs: FloatArray,
    ys: FloatArray,
    order: IntArray,
    counts: IntArray,
    near: tuple[IntArray, IntArray],
    magnitude: FloatArray,
    what: str,
) -> FloatArray:
    """Per set: how far a point left out of the hull may lie outside it (module docstring).

    ``near`` (set, point index) names the points dropped without being certainly inside; only
    a set where such a point is not a copy of a vertex needs slack. ``what`` names the sets in
    an error, as in :func:`convex_hull_batch`.
    """
    near_set, near_idx = near
    sets = np.arange(xs.shape[0])[:, None]
    vx, vy = xs[sets, order], ys[sets, order]
    px, py = xs[near_set, near_idx], ys[near_set, near_idx]
    is_vertex = ((vx[near_set] == px[:, None]) & (vy[near_set] == py[:, None])).any(axis=1)
    near_miss = np.zeros(xs.shape[0], dtype=bool)
    near_miss[near_set[~is_vertex]] = True
    if not near_miss.any():
        return np.zeros(xs.shape[0])
    # sin(alpha / 2) at each vertex from the turn between its incoming and outgoing edges.
    ex = np.roll(vx, -1, axis=1) - vx
    ey = np.roll(vy, -1, axis=1) - vy
    k = np.arange(order.shape[1])[None, :]
    prev = np.where(k == 0, counts[:, None] - 1, k - 1)
    ix, iy = ex[sets, prev], ey[sets, prev]
    norm = np.sqrt((ix * ix + iy * iy) * (ex * ex + ey * ey))
    real = k < counts[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_turn = np.where(real & (norm > 0), (ix * ex + iy * ey) / norm, -1.0)
    sin_half = np.sqrt(np.maximum((1.0 + cos_turn) * 0.5 - 8.0 * U, 0.0))
    sin_half = np.where(real, sin_half, 1.0).min(axis=1)
    sharp = near_miss & (sin_half < _MIN_SIN_HALF)
    if sharp.any():
        bad = int(np.flatnonzero(sharp)[0])
        raise DegeneratePolygonError(
            f"{what} {bad}: a vertex angle below {2 * _MIN_SIN_HALF:.1g} rad with points "
            "within rounding of the boundary; the hull cannot bound its rounding error"
        )
    slack: FloatArray = np.where(
        near_miss, HULL_HALFPLANE * magnitude / np.maximum(sin_half, _MIN_SIN_HALF), 0.0
    )
    return slack


def convex_polygons(
    vertices: npt.ArrayLike | Sequence[npt.ArrayLike],
    counts: npt.ArrayLike | None = None,
    *,
    workspace: Workspace | None = None,
) -> ConvexPolygons:
    """Normalised convex polygons from point lists (SR-SAT-4).

    ``vertices`` is an (N, K, 2) array (with ``counts`` (N,) the number of valid points per
    polygon; all K when omitted) or a sequence of (k_i, 2) arrays. Each polygon becomes the
    convex hull of its points: counter-clockwise, duplicate and collinear points removed.
    Raises :class:`NonFiniteGeometryError` or :class:`DegeneratePolygonError` naming the
    polygon and the bad value.
    """
    if isinstance(vertices, np.ndarray) and vertices.ndim == 3:
        stacked = np.asarray(vertices, dtype=np.float64)
    else:
        items = [np.asarray(v, dtype=np.float64) for v in vertices]  # type: ignore[union-attr]
        for i, item in enumerate(items):
            if item.ndim != 2 or item.shape[1] != 2:
                raise GeometryError(f"polygon {i}: expected a (k, 2) array, got {item.shape}")
        if counts is not None:
            raise GeometryError("convex_polygons: counts apply to an (N, K, 2) array only")
        counts = [len(item) for item in items]
        width = max([*counts, 1])
        stacked = np.zeros((len(items), width, 2))
        for i, item in enumerate(items):
            stacked[i, : len(item)] = item
    if stacked.ndim != 3 or stacked.shape[2] != 2:
        raise GeometryError(f"convex_polygons: expected (N, K, 2) vertices, got {stacked.shape}")
    n, k, _ = stacked.shape
    count = np.full(n, k, dtype=np.int64) if counts is None else np.asarray(counts, dtype=np.int64)
    if count.shape != (n,) or (n and (count.min() < 1 or count.max() > k)):
        raise GeometryError(f"convex_polygons: counts must be (N,) within [1, {k}]")
    few = count < 3
    if few.any():
        bad = int(np.flatnonzero(few)[0])
        raise DegeneratePolygonError(
            f"polygon {bad}: {count[bad]} point(s) given; a polygon needs at least 3 distinct "
            "points"
        )
    if n == 0:
        return no_polygons()
    valid = np.arange(k)[None, :] < count[:, None]
    px = np.where(valid, stacked[:, :, 0], stacked[:, :1, 0])
    py = np.where(valid, stacked[:, :, 1], stacked[:, :1, 1])
    order, hull_counts, slack = convex_hull_batch(px, py, what="polygon", workspace=workspace)
    return polygons_from_hull(px, py, order, hull_counts, slack)


def no_polygons() -> ConvexPolygons:
    """The empty batch (N = 0), padded to the least width a polygon has (K = 3)."""
    return ConvexPolygons(np.zeros((2, 3, 0)), np.zeros(0, np.int64), np.zeros(0))


def polygons_from_hull(
    px: FloatArray, py: FloatArray, order: IntArray, counts: IntArray, slack: FloatArray
) -> ConvexPolygons:
    """The :class:`ConvexPolygons` for the result of :func:`convex_hull_batch` on (px, py)."""
    sets = np.arange(px.shape[0])[:, None]
    out = np.empty((2, order.shape[1], px.shape[0]))
    out[0] = px[sets, order].T
    out[1] = py[sets, order].T
    return ConvexPolygons(vertices_m=out, counts=counts, slack_m=slack)


class PolygonBounds:
    """Per-polygon quick-reject data (SR-SAT-1): axis-aligned box, magnitude, bounding circle.

    ``centre_*`` is the box centre (independent of padding, so every entry point computes the
    same value); ``magnitude_m`` is the largest absolute coordinate (the scale of rounding
    errors); :attr:`radius_m` (computed on first use) is rounded up so the circle certainly
    contains the polygon.
    """

    __slots__ = (
        "_radius",
        "centre_x_m",
        "centre_y_m",
        "magnitude_m",
        "max_x_m",
        "max_y_m",
        "min_x_m",
        "min_y_m",
        "pack",
        "polygons",
        "slack",
    )

    def __init__(self, polygons: ConvexPolygons) -> None:
        v = polygons.vertices_m
        low = np.minimum.reduce(v, axis=1)
        high = np.maximum.reduce(v, axis=1)
        # pack rows: centre x, centre y, magnitude, slack (one gather serves the SAT kernel)
        pack = np.empty((4, polygons.n))
        np.add(low, high, out=pack[:2])
        pack[:2] *= 0.5
        np.maximum(-low, high).max(axis=0, out=pack[2])
        pack[3] = polygons.slack_m
        self.pack = pack
        self.polygons = polygons
        self.min_x_m, self.min_y_m = low[0], low[1]
        self.max_x_m, self.max_y_m = high[0], high[1]
        self.centre_x_m, self.centre_y_m = pack[0], pack[1]
        self.magnitude_m = pack[2]
        self.slack = polygons.slack_m
        self._radius: FloatArray | None = None

    @property
    def radius_m(self) -> FloatArray:
        """Radius of a circle about the box centre that contains the polygon, in metres."""
        if self._radius is None:
            v = self.polygons.vertices_m
            dx = v[0] - self.centre_x_m
            dy = v[1] - self.centre_y_m
            self._radius = np.sqrt((dx * dx + dy * dy).max(axis=0)) + 16.0 * U * self.magnitude_m
        return self._radius


def polygon_bounds(polygons: ConvexPolygons) -> PolygonBounds:
    """Quick-reject data of each polygon."""
    return PolygonBounds(polygons)


def transform_polygons(
    polygons: ConvexPolygons,
    x_m: npt.ArrayLike,
    y_m: npt.ArrayLike,
    theta_rad: npt.ArrayLike,
) -> ConvexPolygons:
    """Each polygon rotated by ``theta_rad`` about the origin, then moved by (x_m, y_m).

    Pose arrays broadcast to (N,). A rigid motion keeps a convex polygon convex and
    counter-clockwise; the rounding of the new coordinates is added to ``slack_m``.
    """
    x, y, theta = (
        np.broadcast_to(np.asarray(a, np.float64), (polygons.n,)) for a in (x_m, y_m, theta_rad)
    )
    for name, value in (("x_m", x), ("y_m", y), ("theta_rad", theta)):
        if not np.all(np.isfinite(value)):
            raise NonFiniteGeometryError(f"transform_polygons: {name} is not finite: {value!r}")
    out = np.empty_like(polygons.vertices_m)
    out[0], out[1] = to_parent((x, y, theta), polygons.vertices_m[0], polygons.vertices_m[1])
    magnitude = np.abs(out).max(axis=(0, 1))
    if np.any(magnitude > MAX_COORD_M):
        raise NonFiniteGeometryError(f"transform_polygons: result exceeds +/-{MAX_COORD_M:g} m")
    return ConvexPolygons(
        vertices_m=out, counts=polygons.counts, slack_m=polygons.slack_m + 8.0 * U * magnitude
    )
