"""Free distance along the robot's own path: the governor's input (SR-RUN-1, SR-STOP-2).

The governor needs, per obstacle, how far the robot can still drive along the path it is
following before its footprint touches that obstacle's predicted zone. The path ahead is
sampled every ``runtime.path_step_m`` up to ``runtime.path_lookahead_m``; the region the
footprint sweeps between two consecutive samples is covered by a convex polygon (the hull of
the footprint at both samples, exact for a straight piece; at a corner, where the heading
changes between samples, a disc about the pivot that holds the footprint turning through any
angle and moving by the step). The free distance to a zone is the arc length of the first piece
that overlaps it (SAT with the tolerance band: "touching" counts), so the robot can reach that
sample without touching it; a zone no piece reaches gets the whole lookahead, which is no more
than the truth. Scan points outside every kept cluster (walls longer than the cluster size
filter, objects with too few returns) are tested the same way against the footprint.

Everything is in the tracking frame (the frame the predictions are in).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pipeline.config import GeometrySection
from pipeline.constructive import disc_points
from pipeline.frames import to_child, to_parent
from pipeline.types import BoolArray, ConvexPolygons, FloatArray, frozen_array
from safety.geometry.contact import contact_pairs
from safety.geometry.polygons import GeometryError, NonFiniteGeometryError, U, convex_polygons
from safety.geometry.sat import SatChecker
from safety.geometry.swept import rectangle_footprint

__all__ = ["PathAhead", "PathClearance", "PathDistances"]

# A heading change between two samples larger than this makes the piece a corner [rad].
_CORNER_RAD = 1e-9
_DISC_SIDES = 16


@dataclass(frozen=True, slots=True)
class PathAhead:
    """The robot's path from its current pose, sampled by arc length (tracking frame).

    ``arc_m`` (S,) starts at 0 and increases; ``x_m``, ``y_m``, ``theta_rad`` (S,) are the
    robot's reference-point poses there. At least two samples.
    """

    arc_m: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    theta_rad: FloatArray

    def __post_init__(self) -> None:
        arrays = [frozen_array(a) for a in (self.arc_m, self.x_m, self.y_m, self.theta_rad)]
        arc, x, y, theta = arrays
        shape = arc.shape
        if len(shape) != 1 or shape[0] < 2 or any(a.shape != shape for a in arrays):
            raise GeometryError(
                "PathAhead: arc_m, x_m, y_m, theta_rad must be 1-D arrays of one length >= 2, "
                "got " + ", ".join(str(a.shape) for a in arrays)
            )
        if not all(np.isfinite(a).all() for a in arrays):
            raise NonFiniteGeometryError("PathAhead: every pose and arc length must be finite")
        if arc[0] != 0.0 or np.any(np.diff(arc) <= 0.0):
            raise GeometryError("PathAhead: arc_m must start at 0 and increase strictly")
        object.__setattr__(self, "arc_m", arc)
        object.__setattr__(self, "x_m", x)
        object.__setattr__(self, "y_m", y)
        object.__setattr__(self, "theta_rad", theta)

    @property
    def length_m(self) -> float:
        """Arc length covered by the samples."""
        return float(self.arc_m[-1])

    @classmethod
    def straight(
        cls, pose: tuple[float, float, float], lookahead_m: float, step_m: float
    ) -> PathAhead:
        """Straight ahead of ``pose`` (x_m, y_m, yaw_rad) for ``lookahead_m``."""
        return cls.along_polyline(
            np.array(
                [
                    [pose[0], pose[1]],
                    [
                        pose[0] + lookahead_m * math.cos(pose[2]),
                        pose[1] + lookahead_m * math.sin(pose[2]),
                    ],
                ]
            ),
            0.0,
            lookahead_m,
            step_m,
        )

    @classmethod
    def along_polyline(
        cls, points_m: npt.ArrayLike, start_arc_m: float, lookahead_m: float, step_m: float
    ) -> PathAhead:
        """The polyline ``points_m`` (N >= 2, 2) from arc length ``start_arc_m`` on, for at
        most ``lookahead_m`` (less where the polyline ends), heading along each segment."""
        pts = np.asarray(points_m, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[0] < 2 or pts.shape[1] != 2 or not np.isfinite(pts).all():
            raise GeometryError(f"PathAhead: polyline must be finite (N >= 2, 2), got {pts.shape}")
        if not (lookahead_m > 0 and step_m > 0 and math.isfinite(start_arc_m)):
            raise GeometryError(
                f"PathAhead: lookahead_m = {lookahead_m!r}, step_m = {step_m!r}: expected > 0"
            )
        seg = np.hypot(*np.diff(pts, axis=0).T)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        start = min(max(start_arc_m, 0.0), float(cum[-1]))
        length = min(lookahead_m, float(cum[-1]) - start)
        if length <= 0.0:  # at the end of the route: a stub that only holds the footprint here
            length = step_m
        n = max(math.ceil(length / step_m - 1e-9), 1)
        arc = np.minimum(np.arange(n + 1) * step_m, length)
        # start >= 0 and arc >= 0, so s >= cum[0] = 0 and the segment index is at least 0.
        s = np.minimum(start + arc, cum[-1])
        k = np.minimum(np.searchsorted(cum, s, side="right") - 1, cum.size - 2)
        d = pts[k + 1] - pts[k]
        frac = (s - cum[k]) / np.where(seg[k] > 0, seg[k], 1.0)
        return cls(
            arc_m=arc,
            x_m=pts[k, 0] + frac * d[:, 0],
            y_m=pts[k, 1] + frac * d[:, 1],
            theta_rad=np.arctan2(d[:, 1], d[:, 0]),
        )


@dataclass(frozen=True, slots=True)
class PathDistances:
    """Free distances [m] along the path: per zone (Z,), and the nearest point on the path
    among the loose scan points (``point_free_m``; the lookahead when none lies on it).

    ``zone_hit`` says whether the zone lies on the sampled path at all; ``n_points_on_path``
    counts the loose points that do.
    """

    zone_free_m: FloatArray
    zone_hit: BoolArray
    point_free_m: float
    n_points_on_path: int
    lookahead_m: float


def _placed(footprint: ConvexPolygons, x: float, y: float, theta: float) -> ConvexPolygons:
    """The footprint at one pose."""
    v = footprint.vertex_list(0)
    return convex_polygons([np.stack(to_parent((x, y, theta), v[:, 0], v[:, 1]), axis=1)])


class PathClearance:
    """Free distance along a :class:`PathAhead` for the configured rectangular footprint.

    Holds the SAT checker's scratch buffers: one per thread.
    """

    def __init__(self, geometry: GeometrySection) -> None:
        self.length_m = float(geometry.footprint_length_m)
        self.width_m = float(geometry.footprint_width_m)
        self.footprint = rectangle_footprint(self.length_m, self.width_m)
        self.sat = SatChecker(geometry.contact_tolerance_m)
        self.tolerance_m = float(geometry.contact_tolerance_m)

    def pieces(self, path: PathAhead) -> ConvexPolygons:
        """One convex polygon per piece between consecutive samples (module docstring).

        A straight piece is the footprint stretched along its heading to the next sample (the
        exact hull of the two placed rectangles, built directly: no hull computation); a
        corner piece is the pivot disc's circumscribed polygon. ``slack_m`` covers the
        rounding of these vertices (a few ulp of the largest coordinate).
        """
        n = path.arc_m.shape[0] - 1
        x0, y0, th = path.x_m[:-1], path.y_m[:-1], path.theta_rad[:-1]
        hl, hw = 0.5 * self.length_m, 0.5 * self.width_m
        # Rear right, front right, front left, rear left: counter-clockwise.
        rear, front = np.full_like(x0, -hl), hl + np.diff(path.arc_m)
        along = np.stack([rear, front, front, rear])
        across = np.array([-hw, -hw, hw, hw])[:, None]
        verts = np.empty((2, _DISC_SIDES, n))
        verts[0, :4], verts[1, :4] = to_parent((x0, y0, th), along, across)
        verts[:, 4:] = verts[:, :1]
        counts = np.full(n, 4)
        corner = self._corners(path)
        if corner.any():
            disc = disc_points(x0[corner], y0[corner], self._pivot_radii(path)[corner], _DISC_SIDES)
            verts[:, :, corner] = disc.transpose(2, 1, 0)
            counts[corner] = _DISC_SIDES
        magnitude = np.abs(verts).max(axis=(0, 1))  # n >= 1: a path has two samples or more
        return ConvexPolygons(vertices_m=verts, counts=counts, slack_m=16.0 * U * (1.0 + magnitude))

    def _corners(self, path: PathAhead) -> BoolArray:
        turn = np.abs(np.angle(np.exp(1j * np.diff(path.theta_rad))))
        corner: BoolArray = turn > _CORNER_RAD
        return corner

    def _pivot_radii(self, path: PathAhead) -> FloatArray:
        half_diag = 0.5 * math.hypot(self.length_m, self.width_m)
        radii: FloatArray = half_diag + np.diff(path.arc_m) + self.tolerance_m
        return radii

    def free_distances(
        self,
        path: PathAhead,
        zones: ConvexPolygons,
        points_x_m: FloatArray,
        points_y_m: FloatArray,
    ) -> PathDistances:
        """Free distance to every zone and to the nearest loose point (module docstring)."""
        arc = path.arc_m
        lookahead = path.length_m
        zone_free = np.full(zones.n, lookahead)
        zone_hit: BoolArray = np.zeros(zones.n, dtype=bool)
        pieces = self.pieces(path)
        if zones.n:
            hits = self.sat.overlap_all(pieces, zones)  # (S - 1, Z)
            zone_hit = np.asarray(hits.any(axis=0))
            zone_free[zone_hit] = arc[hits.argmax(axis=0)[zone_hit]]
        point_free, on_path = lookahead, 0
        px, py = points_x_m, points_y_m
        if px.size:
            # Only points in the pieces' bounding box can lie on the path (most of a scan).
            v = pieces.vertices_m
            pad = 2.0 * self.tolerance_m
            near = (
                (px >= v[0].min() - pad)
                & (px <= v[0].max() + pad)
                & (py >= v[1].min() - pad)
                & (py <= v[1].max() + pad)
            )
            px, py = px[near], py[near]
        if px.size:
            hit = self._points_on_pieces(path, px, py)  # (S - 1, P)
            on = hit.any(axis=0)
            on_path = int(np.count_nonzero(on))
            if on_path:
                point_free = float(arc[hit.argmax(axis=0)[on]].min())
        return PathDistances(zone_free, zone_hit, point_free, on_path, lookahead)

    def distances_now(self, path: PathAhead, bodies: ConvexPolygons) -> FloatArray:
        """Euclidean distance [m] from the footprint at the path's first pose to each body (0
        where they touch): for objects that may move in any direction, the passive-safety
        reading of free distance (an object closing at V cannot reach the robot sooner)."""
        if bodies.n == 0:
            return np.zeros(0)
        pose = (float(path.x_m[0]), float(path.y_m[0]), float(path.theta_rad[0]))
        placed = _placed(self.footprint, *pose)
        robot = placed.take([0] * bodies.n)
        distance: FloatArray = contact_pairs(robot, bodies).distance_m
        return distance

    def _points_on_pieces(
        self, path: PathAhead, px: FloatArray, py: FloatArray
    ) -> npt.NDArray[np.bool_]:
        """(S - 1, P): point p lies in piece k (the footprint at sample k stretched forward by
        the step; the pivot disc at a corner)."""
        x0, y0, th = path.x_m[:-1, None], path.y_m[:-1, None], path.theta_rad[:-1, None]
        step = np.diff(path.arc_m)[:, None]
        along, across = to_child((x0, y0, th), px[None, :], py[None, :])
        tol = self.tolerance_m
        hl, hw = 0.5 * self.length_m + tol, 0.5 * self.width_m + tol
        inside: npt.NDArray[np.bool_] = (
            (along >= -hl) & (along <= hl + step) & (np.abs(across) <= hw)
        )
        corner = self._corners(path)
        if corner.any():
            r = self._pivot_radii(path)[:, None]
            dx, dy = px[None, :] - x0, py[None, :] - y0
            inside[corner] = (np.hypot(dx, dy) <= r)[corner]
        return inside
