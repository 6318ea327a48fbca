"""Planar outlines for the simulator: closed polygons as flat vertex arrays, and distances.

An :class:`Outline` is one or more closed, counter-clockwise simple polygons ("parts") stored as
one flat ``(V, 2)`` vertex array plus edge index arrays, so that a whole set of outlines can be
posed and ray cast with array operations (SR-SIM-1). Parts may overlap (a forklift's fork tines
touch its mast): a ray entering the union first crosses the boundary of some part, so casting
against every part's edges finds the first hit of the union.

Distances (:func:`edge_set_distance`) serve the ego robot's separation record (SR-SIM-5) and
the no-overlap checks of the scenario builders (SR-SIM-3). Lengths are metres, angles radians.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.frames import to_parent
from pipeline.types import BoolArray, FloatArray, IntArray, frozen_array

__all__ = [
    "Outline",
    "chamfered_rectangle",
    "edge_set_distance",
    "ensure_ccw",
    "outline_distances",
    "points_in_parts",
    "pose_points",
    "rectangle",
    "regular_polygon",
    "segment_distance",
    "signed_area",
]


def signed_area(polygon: FloatArray) -> float:
    """Shoelace area of a closed polygon ``(N, 2)``; positive when counter-clockwise."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def ensure_ccw(polygon: FloatArray) -> FloatArray:
    """The polygon with counter-clockwise vertex order (the ray caster's culling relies on it)."""
    poly = np.asarray(polygon, dtype=np.float64)
    if poly.ndim != 2 or poly.shape[1] != 2 or poly.shape[0] < 3:
        raise ValueError(f"polygon must have shape (N >= 3, 2), got {poly.shape}")
    area = signed_area(poly)
    if area == 0.0:
        raise ValueError("polygon has zero area")
    return poly if area > 0 else poly[::-1].copy()


def rectangle(x_min: float, x_max: float, y_min: float, y_max: float) -> FloatArray:  # metres, CCW
    """Axis-aligned rectangle ``[x_min, x_max] x [y_min, y_max]`` as a CCW polygon."""
    if not (x_max > x_min and y_max > y_min):
        raise ValueError(f"empty rectangle [{x_min}, {x_max}] x [{y_min}, {y_max}]")
    return np.array(
        [[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max]], dtype=np.float64
    )


def chamfered_rectangle(
    x_min: float,
    x_max: float,
    y_min: float,
    y_max: float,
    *,
    rear_chamfer_m: float = 0.0,
    front_chamfer_m: float = 0.0,
) -> FloatArray:
    """Rectangle with 45-degree cut corners at the rear (-x) and/or front (+x) end, CCW."""
    c_r, c_f = rear_chamfer_m, front_chamfer_m
    half = min(x_max - x_min, y_max - y_min) / 2.0
    if not (0.0 <= c_r < half and 0.0 <= c_f < half):
        raise ValueError(f"chamfers {c_r}, {c_f} m must be in [0, {half}) m")
    pts = [
        (x_min + c_r, y_min),
        (x_max - c_f, y_min),
        (x_max, y_min + c_f),
        (x_max, y_max - c_f),
        (x_max - c_f, y_max),
        (x_min + c_r, y_max),
        (x_min, y_max - c_r),
        (x_min, y_min + c_r),
    ]
    out: list[tuple[float, float]] = []
    for p in pts:  # drop the duplicate vertices a zero chamfer produces
        if not out or (abs(p[0] - out[-1][0]) > 1e-12 or abs(p[1] - out[-1][1]) > 1e-12):
            out.append(p)
    if abs(out[0][0] - out[-1][0]) <= 1e-12 and abs(out[0][1] - out[-1][1]) <= 1e-12:
        out.pop()
    return np.array(out, dtype=np.float64)


def regular_polygon(
    radius_m: float, n: int, center: tuple[float, float] = (0.0, 0.0)
) -> FloatArray:
    """Regular ``n``-gon of circumradius ``radius_m`` (a circle's stand-in), CCW."""
    if radius_m <= 0 or n < 3:
        raise ValueError(f"regular_polygon needs radius > 0 and n >= 3, got {radius_m}, {n}")
    ang = np.arange(n) * (2.0 * np.pi / n)
    return np.stack(
        [center[0] + radius_m * np.cos(ang), center[1] + radius_m * np.sin(ang)], axis=1
    )


@dataclass(frozen=True, slots=True)
class Outline:
    """Closed CCW parts in one flat vertex array (body frame, metres).

    ``edge_from[k]`` and ``edge_to[k]`` index the two vertices of edge ``k``; ``part_starts``
    has ``P + 1`` entries, part ``p`` owning vertices (and edges) ``part_starts[p]`` up to
    ``part_starts[p + 1]``.
    """

    vertices_m: FloatArray
    edge_from: IntArray
    edge_to: IntArray
    part_starts: IntArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices_m", frozen_array(self.vertices_m))
        for name in ("edge_from", "edge_to", "part_starts"):
            object.__setattr__(self, name, frozen_array(getattr(self, name), np.int64))

    @staticmethod
    def from_parts(parts: Sequence[FloatArray]) -> Outline:
        """Build from closed polygons (any orientation; stored CCW)."""
        if not parts:
            raise ValueError("an outline needs at least one part")
        ccw = [ensure_ccw(p) for p in parts]
        sizes = np.array([p.shape[0] for p in ccw], dtype=np.int64)
        starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        idx = np.arange(starts[-1], dtype=np.int64)
        part_of = np.repeat(np.arange(len(ccw)), sizes)
        nxt = idx + 1
        wrap = nxt == starts[part_of + 1]
        nxt[wrap] = starts[part_of[wrap]]
        return Outline(
            vertices_m=np.concatenate(ccw, axis=0),
            edge_from=idx,
            edge_to=nxt,
            part_starts=starts,
        )

    @property
    def n_vertices(self) -> int:
        """Number of vertices (= number of edges)."""
        return int(self.vertices_m.shape[0])

    @property
    def n_parts(self) -> int:
        """Number of closed parts."""
        return int(self.part_starts.shape[0] - 1)

    def parts(self) -> list[FloatArray]:
        """The parts as separate ``(N, 2)`` arrays."""
        s = self.part_starts
        return [self.vertices_m[s[p] : s[p + 1]] for p in range(self.n_parts)]

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of all vertices."""
        v = self.vertices_m
        return (
            float(v[:, 0].min()),
            float(v[:, 0].max()),
            float(v[:, 1].min()),
            float(v[:, 1].max()),
        )


def pose_points(
    points: FloatArray, x_m: FloatArray, y_m: FloatArray, heading_rad: FloatArray
) -> FloatArray:
    """Body-frame points into the world frame for ``T`` poses at once.

    ``points`` is ``(V, 2)`` (the same for every pose) or ``(T, V, 2)``; the pose arrays are
    ``(T,)``. Returns ``(T, V, 2)``.
    """
    pose = (x_m[:, None], y_m[:, None], heading_rad[:, None])
    px, py = to_parent(pose, points[..., 0], points[..., 1])
    out: FloatArray = np.stack(np.broadcast_arrays(px, py), axis=-1)
    return out


def _cross(ax: FloatArray, ay: FloatArray, bx: FloatArray, by: FloatArray) -> FloatArray:
    return ax * by - ay * bx


def _point_segment(
    px: FloatArray, py: FloatArray, ax: FloatArray, ay: FloatArray, bx: FloatArray, by: FloatArray
) -> FloatArray:
    ex, ey = bx - ax, by - ay
    len2 = ex * ex + ey * ey
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(len2 > 0, ((px - ax) * ex + (py - ay) * ey) / len2, 0.0)
    u = np.clip(u, 0.0, 1.0)
    return np.hypot(px - (ax + u * ex), py - (ay + u * ey))


def segment_distance(p0: FloatArray, p1: FloatArray, q0: FloatArray, q1: FloatArray) -> FloatArray:
    """Distance between segments p0-p1 and q0-q1 (broadcast (..., 2)); 0 where they meet."""
    d = np.minimum(
        np.minimum(
            _point_segment(p0[..., 0], p0[..., 1], q0[..., 0], q0[..., 1], q1[..., 0], q1[..., 1]),
            _point_segment(p1[..., 0], p1[..., 1], q0[..., 0], q0[..., 1], q1[..., 0], q1[..., 1]),
        ),
        np.minimum(
            _point_segment(q0[..., 0], q0[..., 1], p0[..., 0], p0[..., 1], p1[..., 0], p1[..., 1]),
            _point_segment(q1[..., 0], q1[..., 1], p0[..., 0], p0[..., 1], p1[..., 0], p1[..., 1]),
        ),
    )
    rx, ry = p1[..., 0] - p0[..., 0], p1[..., 1] - p0[..., 1]
    sx, sy = q1[..., 0] - q0[..., 0], q1[..., 1] - q0[..., 1]
    o1 = _cross(rx, ry, q0[..., 0] - p0[..., 0], q0[..., 1] - p0[..., 1])
    o2 = _cross(rx, ry, q1[..., 0] - p0[..., 0], q1[..., 1] - p0[..., 1])
    o3 = _cross(sx, sy, p0[..., 0] - q0[..., 0], p0[..., 1] - q0[..., 1])
    o4 = _cross(sx, sy, p1[..., 0] - q0[..., 0], p1[..., 1] - q0[..., 1])
    # Collinear pairs (all four zero) are left to the endpoint distances, which are exact there.
    crossing = (o1 * o2 <= 0) & (o3 * o4 <= 0) & ~((o1 == 0) & (o2 == 0) & (o3 == 0) & (o4 == 0))
    return np.where(crossing, 0.0, d)


def points_in_parts(points: FloatArray, vertices: FloatArray, outline: Outline) -> BoolArray:
    """Whether each point lies inside each part (crossing number), ``(..., N, P)``.

    ``points`` is ``(..., N, 2)``; ``vertices`` the posed ``(..., V, 2)`` vertex array of
    ``outline`` (leading batch dimensions broadcast).
    """
    a = vertices[..., outline.edge_from, :][..., None, :, :]  # (..., 1, E, 2)
    b = vertices[..., outline.edge_to, :][..., None, :, :]
    px = points[..., :, None, 0]  # (..., N, 1)
    py = points[..., :, None, 1]
    ay, by = a[..., 1], b[..., 1]
    straddle = (ay > py) != (by > py)
    with np.errstate(invalid="ignore", divide="ignore"):
        x_cross = a[..., 0] + (py - ay) * (b[..., 0] - a[..., 0]) / (by - ay)
    hits = (straddle & (px < x_cross)).astype(np.int64)
    counts = np.add.reduceat(hits, outline.part_starts[:-1], axis=-1)
    return (counts % 2) == 1  # type: ignore[no-any-return]


def outline_distances(
    vertices_a: FloatArray,
    outline_a: Outline,
    vertices_b: FloatArray,
    outline_b: Outline,
    part_owner_b: IntArray,
    n_owners: int,
) -> FloatArray:
    """Distance from posed outline ``a`` to each owner's parts of posed outline ``b``.

    ``vertices_a`` ``(..., Va, 2)`` and ``vertices_b`` ``(..., Vb, 2)`` are posed vertex arrays
    (leading batch dimensions, e.g. time, broadcast); ``part_owner_b[p]`` (in
    ``0 .. n_owners - 1``) says which owner part ``p`` of ``b`` belongs to. Returns
    ``(..., n_owners)``; 0 means touching, crossing or containment; owners without parts get
    ``inf``. Serves the ego robot's separation record (SR-SIM-5) and the no-overlap checks
    (SR-SIM-3).
    """
    a0 = vertices_a[..., outline_a.edge_from, :][..., :, None, :]
    a1 = vertices_a[..., outline_a.edge_to, :][..., :, None, :]
    b0 = vertices_b[..., outline_b.edge_from, :][..., None, :, :]
    b1 = vertices_b[..., outline_b.edge_to, :][..., None, :, :]
    per_edge = segment_distance(a0, a1, b0, b1).min(axis=-2)  # (..., Eb)
    starts = outline_b.part_starts[:-1]
    per_part = np.minimum.reduceat(per_edge, starts, axis=-1)  # (..., Pb)
    a_in_b = points_in_parts(vertices_a, vertices_b, outline_b).any(axis=-2)  # (..., Pb)
    b_in_a = points_in_parts(vertices_b, vertices_a, outline_a).any(axis=-1)  # (..., Vb)
    b_in_a_part = np.logical_or.reduceat(b_in_a, starts, axis=-1)
    per_part = np.where(a_in_b | b_in_a_part, 0.0, per_part)
    batch = per_part.shape[:-1]
    flat = per_part.reshape(-1, per_part.shape[-1])
    out = np.full((flat.shape[0], n_owners), np.inf)
    rows = np.arange(flat.shape[0])[:, None]
    np.minimum.at(out, (rows, np.asarray(part_owner_b)[None, :]), flat)
    return out.reshape((*batch, n_owners))


def edge_set_distance(
    vertices_a: FloatArray, outline_a: Outline, vertices_b: FloatArray, outline_b: Outline
) -> float:
    """Distance between two posed outlines (0 when they touch, cross or one contains the other)."""
    owners = np.zeros(outline_b.n_parts, dtype=np.int64)
    return float(outline_distances(vertices_a, outline_a, vertices_b, outline_b, owners, 1)[0])
