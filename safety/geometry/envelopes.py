"""Obstacle envelopes: predicted regions grown by body and margin (SR-PRED-1, SR-STOP-4).

Each prediction row (:class:`~pipeline.types.Predictions`) becomes one convex polygon: the hull
of the reach region plus a disc of radius ``body_radius_m + margin_m`` (a Minkowski sum; the
disc is a circumscribed polygon, so the envelope contains the exact grown region). The margin
is chosen by the stopping model's own ``StoppingParams.margin_for(confidence, near_reversal)``
(:mod:`safety.model.stopping`: the function whose monotonicity in confidence z3 proves, SR-STOP-4);
the tier code by the same ``tier_value`` selector. There is no second margin table here.

Per envelope the governor also needs how fast the object may close in
(``closing_speed_mps``), taken from the stopping model's class speeds:

* unscored or low-confidence (prediction mode UNKNOWN): the worst closing speed of any class
  and, through ``margin_for`` at confidence 0, the near-reversal (largest) margin: the
  conservative fallback for tracks the classifier cannot score;
* near reversal (modes STOP and REVERSE): the reversing forklift's speed;
* a person: the ISO 13855 walking speed (``stopping.person_speed_mps``);
* stationary and static classes: the static speed (0 by default);
* other moving classes: the larger of the static speed and the prediction's speed bound;
* then, whatever the class: at least the person speed where the track may be a person
  (``Predictions.person_compatible``; :func:`safety.model.stopping.person_floor_mps`, SR-CLS-8).

When the classifier cannot run at all, :func:`pipeline.classify.model.unscored` gives every track
class -1, and every track then gets this fallback.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from pipeline.classify.model import PERSON_CLASS
from pipeline.config import PredictSection, SafecaseConfig
from pipeline.constructive import disc_points, minkowski
from pipeline.errors import GeometryError
from pipeline.frames import checked_pose, inverse, is_identity
from pipeline.types import (
    BoolArray,
    ConvexPolygons,
    Envelopes,
    FloatArray,
    PredictionMode,
    Predictions,
)
from safety.geometry.polygons import MAX_COORD_M, convex_polygons, no_polygons, transform_polygons
from safety.model.stopping import StoppingParams, person_floor_mps, tier_value

__all__ = ["ROUNDING_M", "EnvelopeBuilder", "body_polygons", "grown_polygons"]

_TIER_CODES = (0, 1, 2)  # Tier.HIGH, Tier.MEDIUM, Tier.NEAR_REVERSAL
# Added to every growth radius [m]: the polygons are built in floats from points on the exact
# region's boundary, and this keeps a rounding error (~1e-15 m here) on the safe side.
ROUNDING_M = 1e-9
# A disc row skips the hull when its vertices stand this far (relative to its coordinates)
# from every chord (:func:`_disc_rows`); the hull's own allowance is about 3e-15.
_RING_MIN = 1e-6


def grown_polygons(reach_xy_m: FloatArray, radius_m: FloatArray, sides: int) -> ConvexPolygons:
    """Convex polygons containing each reach region (n, P, 2; counter-clockwise vertices) grown
    by a disc of ``radius_m`` (plus :data:`ROUNDING_M`, so float rounding of the construction
    cannot leave a point of the exact region outside; SR-PRED-1).

    The polygons are the convex hull of the Minkowski points; a row that is a wide disc around
    one point (:func:`_disc_rows`) is read off without the hull, with the same arrays."""
    n = reach_xy_m.shape[0]
    if n == 0:
        return no_polygons()
    radius = np.asarray(radius_m, dtype=np.float64) + ROUNDING_M
    discs = disc_points(np.zeros(n), np.zeros(n), radius, sides)
    points = minkowski(reach_xy_m, discs)
    ring = _disc_rows(radius, points, sides)
    if not ring.any():
        return convex_polygons(points)
    return _merged(points, ring, sides)


def _disc_rows(radius: FloatArray, points: FloatArray, sides: int) -> BoolArray:
    """Rows whose grown polygon is their disc's ``sides`` points as they stand: the reach added
    no edge that survives rounding (it is one point), and the disc is wide against rounding
    at the row's coordinates.

    Such a row's points (``points``, from :func:`minkowski`) are the disc's vertices in
    counter-clockwise order, repeated where the reach adds zero-length edges: exactly ``sides``
    distinct consecutive points. A vertex of a regular ``sides``-gon of circumradius R lies at
    least ``2 R sin^2(pi / sides)`` from the line through any two other vertices, so when that
    is above :data:`_RING_MIN` times the row's largest coordinate (nine orders of magnitude
    above the hull's rounding allowance, ``HULL_HALFPLANE``) every point is certainly a vertex
    and the convex hull would return exactly these points, without slack. A row with a
    non-finite coordinate is never wide (NaN compares false); one beyond the coordinates the
    hull accepts is left to the hull, which refuses it.
    """
    magnitude = np.abs(points).max(axis=(1, 2))
    depth = 2.0 * radius * math.sin(math.pi / sides) ** 2
    found: BoolArray = (
        (depth >= _RING_MIN * magnitude)
        & (magnitude <= MAX_COORD_M)
        & (_steps(points).sum(axis=1) == sides)
    )
    return found


def _steps(points: FloatArray) -> BoolArray:
    """(n, P): each point differs from the one before it (the first always counts)."""
    step = np.ones(points.shape[:2], dtype=bool)
    step[:, 1:] = (points[:, 1:] != points[:, :-1]).any(axis=2)
    return step


def _merged(points: FloatArray, ring: BoolArray, sides: int) -> ConvexPolygons:
    """The convex polygons of ``points``: the ``ring`` rows (:func:`_disc_rows`) read off in
    the hull's order (counter-clockwise from the lowest-x point, ties to the lowest y), the
    others through the hull; the same arrays the hull gives for the whole batch."""
    n = points.shape[0]
    rest = np.flatnonzero(~ring)
    try:
        other = convex_polygons(points[rest])
    except GeometryError:
        # The whole batch raises the same error, naming the row by its index in the batch.
        return convex_polygons(points)
    idx = np.flatnonzero(ring)
    pts = points[idx]
    verts = pts[_steps(pts)].reshape(idx.size, sides, 2)
    x, y = verts[:, :, 0], verts[:, :, 1]
    start = np.where(x == x.min(axis=1, keepdims=True), y, np.inf).argmin(axis=1)
    turn = (start[:, None] + np.arange(sides)[None, :]) % sides
    rows = np.arange(idx.size)[:, None]
    discs = ConvexPolygons(
        np.stack([x[rows, turn].T, y[rows, turn].T]), np.full(idx.size, sides), np.zeros(idx.size)
    )
    counts = np.full(n, sides)
    counts[rest] = other.counts
    slack = np.zeros(n)
    slack[rest] = other.slack_m
    k = int(counts.max())
    out = np.empty((2, k, n))
    out[:, :, idx] = discs.padded_vertices(k)
    out[:, :, rest] = other.padded_vertices(k)
    return ConvexPolygons(vertices_m=out, counts=counts, slack_m=slack)


def body_polygons(predictions: Predictions, sides: int) -> ConvexPolygons:
    """Where any part of each object may be within the horizon (no safety margin)."""
    return grown_polygons(predictions.reach_xy_m, predictions.body_radius_m, sides)


class EnvelopeBuilder:
    """Turns predictions into envelopes for one configuration (SR-PRED-1, SR-STOP-4).

    ``params`` overrides the stopping parameters (e.g. a measured latency bound); the margin
    and closing speeds come from it.
    """

    def __init__(self, section: PredictSection, params: StoppingParams) -> None:
        self.params = params
        self.sides = section.disc_sides

    @classmethod
    def from_config(
        cls, config: SafecaseConfig, params: StoppingParams | None = None
    ) -> EnvelopeBuilder:
        """The builder of ``config`` (its stopping parameters unless ``params`` is given)."""
        stopping = params if params is not None else StoppingParams.from_config(config)
        return cls(config.predict, stopping)

    def margins(
        self, confidence: npt.ArrayLike, near_reversal: npt.ArrayLike
    ) -> tuple[FloatArray, npt.NDArray[np.int64]]:
        """(margin_m, tier code) per obstacle, from the stopping model's one definition."""
        conf = np.asarray(confidence, dtype=np.float64)
        near = np.asarray(near_reversal, dtype=np.bool_)
        p = self.params
        margin = np.asarray(p.margin_for(conf, near), dtype=np.float64)
        tier = tier_value(conf, near, p.high_confidence_min, p.medium_confidence_min, _TIER_CODES)
        return np.broadcast_to(margin, conf.shape).copy(), np.broadcast_to(
            np.asarray(tier, dtype=np.int64), conf.shape
        ).copy()

    def closing_speeds(self, predictions: Predictions, class_names: tuple[str, ...]) -> FloatArray:
        """Closing speed [m/s] the governor must assume per prediction row (module docstring)."""
        p = self.params
        mode = predictions.mode
        static = float(p.static_speed_mps)
        closing = np.maximum(predictions.speed_mps, static)
        still = mode == int(PredictionMode.FOOTPRINT)
        closing[still] = static
        person = class_names.index(PERSON_CLASS) if PERSON_CLASS in class_names else -2
        closing[(predictions.class_index == person) & ~still] = float(p.person_speed_mps)
        closing[predictions.near_reversal] = float(p.forklift_speed_mps)
        closing[mode == int(PredictionMode.UNKNOWN)] = float(p.worst_closing_speed_mps)
        floored: FloatArray = np.asarray(
            person_floor_mps(closing, predictions.person_compatible, float(p.person_speed_mps)),
            dtype=np.float64,
        )
        return floored

    def build(
        self,
        predictions: Predictions,
        class_names: tuple[str, ...],
        robot_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> Envelopes:
        """Envelopes of every prediction row, in the robot frame.

        ``robot_pose`` is the robot's (x_m, y_m, yaw_rad) in the frame the predictions are in
        (the tracking frame); the envelopes are moved into the robot's own frame, where the
        swept-path check and the costmap work. Unknown-mode rows carry confidence 0 (the
        classifier's value does not apply to them).
        """
        unknown = predictions.mode == int(PredictionMode.UNKNOWN)
        confidence = np.where(unknown, 0.0, predictions.confidence)
        margin, tier = self.margins(confidence, predictions.near_reversal)
        polygons = grown_polygons(
            predictions.reach_xy_m, predictions.body_radius_m + margin, self.sides
        )
        pose = checked_pose(robot_pose)
        if not is_identity(pose) and polygons.n:
            polygons = transform_polygons(polygons, *inverse(pose))
        return Envelopes(
            stamp_s=predictions.stamp_s,
            polygons=polygons,
            track_id=predictions.track_id,
            mode=predictions.mode,
            class_index=predictions.class_index,
            tier=tier,
            margin_m=margin,
            closing_speed_mps=self.closing_speeds(predictions, class_names),
            confidence=confidence,
            near_reversal=predictions.near_reversal,
        )
