"""Convex polygons and swept-path reports (SR-SAT-*)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pipeline.errors import DegeneratePolygonError, GeometryError, NonFiniteGeometryError
from pipeline.types.core import BoolArray, FloatArray, IntArray, frozen_array


@dataclass(frozen=True, slots=True)
class ConvexPolygons:
    """N convex polygons in metres, counter-clockwise, vertex-major (SR-SAT-*).

    ``vertices_m`` has shape (2, K, N): ``[0]`` holds x, ``[1]`` holds y; column ``n`` holds
    polygon ``n``'s ``counts[n]`` vertices followed by copies of its first vertex up to K. The
    padding repeats a vertex (which changes no projection) and adds zero-length edges (which
    never separate), so the SAT kernels need no masks. The vertex index leads because numpy
    reduces over a leading axis as whole-row operations, 10-30x faster than over a short
    trailing axis; x and y are stacked so one gather moves both. ``slack_m`` (N,) bounds how
    far, in metres, a point given to the normalisation that built the polygon may lie outside
    it (rounding in the hull); the collision check adds it to its clearance threshold.

    Build these with :func:`safety.geometry.polygons.convex_polygons` (which normalises: hull,
    counter-clockwise order, duplicates and collinear points removed); this constructor only
    checks shapes, finiteness and padding.
    """

    vertices_m: FloatArray
    counts: IntArray
    slack_m: FloatArray

    def __post_init__(self) -> None:
        vertices: FloatArray = np.array(self.vertices_m, dtype=np.float64, order="C", copy=True)
        counts: IntArray = np.array(self.counts, dtype=np.int64, copy=True)
        slack: FloatArray = np.array(self.slack_m, dtype=np.float64, copy=True)
        for array in (vertices, counts, slack):
            array.flags.writeable = False
        if vertices.ndim != 3 or vertices.shape[0] != 2 or vertices.shape[1] < 3:
            raise GeometryError(
                f"ConvexPolygons: vertices_m must have shape (2, K >= 3, N), got {vertices.shape}"
            )
        k, n = vertices.shape[1], vertices.shape[2]
        if counts.shape != (n,) or slack.shape != (n,):
            raise GeometryError(
                f"ConvexPolygons: counts {counts.shape} and slack_m {slack.shape} must have "
                f"shape ({n},)"
            )
        # One reduction: a sum is finite exactly when every (bounded) term is.
        if not np.isfinite(vertices.sum()) and not np.all(np.isfinite(vertices)):
            bad = np.argwhere(~np.isfinite(vertices))[0]
            raise NonFiniteGeometryError(
                f"ConvexPolygons: vertex {bad[1]} of polygon {bad[2]} is not finite "
                f"({float(vertices[tuple(bad)])!r}); expected finite coordinates in metres"
            )
        if n == 0:
            pass
        elif counts.min() < 3 or counts.max() > k:
            raise DegeneratePolygonError(
                f"ConvexPolygons: counts must lie in [3, {k}], got {int(counts.min())}"
            )
        elif not (slack.min() >= 0.0 and np.isfinite(slack.sum())):
            raise GeometryError("ConvexPolygons: slack_m must be finite and >= 0")
        # Padding content cannot make a "clear" verdict unsound (a separating axis proves the
        # hull of all K points apart); checking the last row catches misuse such as zeros.
        elif ((vertices[:, -1, :] != vertices[:, 0, :]).any(axis=0) & (counts < k)).any():
            raise GeometryError("ConvexPolygons: padding must repeat each polygon's first vertex")
        object.__setattr__(self, "vertices_m", vertices)
        object.__setattr__(self, "counts", counts)
        object.__setattr__(self, "slack_m", slack)

    @property
    def n(self) -> int:
        """Number of polygons."""
        return int(self.vertices_m.shape[2])

    @property
    def k(self) -> int:
        """Padded vertex count K."""
        return int(self.vertices_m.shape[1])

    def vertex_list(self, i: int) -> FloatArray:
        """Polygon ``i``'s vertices as a (counts[i], 2) array, counter-clockwise."""
        count = int(self.counts[i])
        return np.ascontiguousarray(self.vertices_m[:, :count, i].T)

    def padded_vertices(self, k: int) -> FloatArray:
        """``vertices_m`` padded to ``k`` (at least K) vertices with copies of each polygon's
        first vertex, as a fresh (2, k, N) array."""
        if k < self.k:
            raise GeometryError(f"ConvexPolygons: cannot pad {self.k} vertices to {k}")
        out = np.empty((2, k, self.n))
        out[:, : self.k] = self.vertices_m
        out[:, self.k :] = self.vertices_m[:, :1]
        return out

    def take(self, indices: npt.ArrayLike) -> ConvexPolygons:
        """The polygons at ``indices`` (in that order), with the same padding K."""
        idx = np.asarray(indices, dtype=np.int64)
        return ConvexPolygons(
            vertices_m=self.vertices_m[:, :, idx],
            counts=self.counts[idx],
            slack_m=self.slack_m[idx],
        )


@dataclass(frozen=True, slots=True)
class SweptPathReport:
    """Which candidate trajectories are blocked, by what and when (SR-SAT-3).

    For T trajectories and O obstacle envelopes: ``blocked`` (T, O) is True where the swept
    hull of trajectory t overlaps envelope o. ``contact_step`` (T, O) is the first sample
    index k whose segment hull (the hull of the footprints at k and k+1) touches the envelope,
    -1 where the pair is clear, and 0 where only the whole-path hull touches it (a concave
    pocket of a curved path: reported as contact now, the conservative answer; ``hull_only``
    marks these). ``earliest_contact_s`` (T,) is ``step_s`` times the smallest contact step
    of the trajectory (``inf`` when clear) and ``first_obstacle`` (T,) the envelope that
    gives it (-1 when clear). ``gated`` (O,) marks envelopes skipped by the distance
    pre-gate because no swept hull can reach them.
    """

    blocked: BoolArray
    contact_step: IntArray
    hull_only: BoolArray
    earliest_contact_s: FloatArray
    first_obstacle: IntArray
    gated: BoolArray
    step_s: float

    def __post_init__(self) -> None:
        blocked = frozen_array(self.blocked, dtype=np.bool_)
        if blocked.ndim != 2:
            raise ValueError(f"SweptPathReport: blocked must be (T, O), got {blocked.shape}")
        t, o = blocked.shape
        shapes = {
            "contact_step": (self.contact_step, (t, o), np.int64),
            "hull_only": (self.hull_only, (t, o), np.bool_),
            "earliest_contact_s": (self.earliest_contact_s, (t,), np.float64),
            "first_obstacle": (self.first_obstacle, (t,), np.int64),
            "gated": (self.gated, (o,), np.bool_),
        }
        object.__setattr__(self, "blocked", blocked)
        for name, (value, shape, dtype) in shapes.items():
            array = frozen_array(value, dtype=dtype)
            if array.shape != shape:
                raise ValueError(f"SweptPathReport: {name} must have shape {shape}")
            object.__setattr__(self, name, array)

    @property
    def blocked_trajectories(self) -> IntArray:
        """Indices of the trajectories blocked by at least one envelope."""
        return np.flatnonzero(self.blocked.any(axis=1)).astype(np.int64)
