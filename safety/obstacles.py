"""What the governor is given: predicted zones, pedestrians, loose points (SR-RUN-1, -3).

Helpers of :mod:`safety.runtime` that turn the perception stages' outputs into the regions the
path clearance measures and the rows :class:`safety.model.decision.GovernorInputs` holds (see the
runtime's module docstring for the reasoning), plus the operating-domain check on object speed.
All regions are in the tracking frame unless they are envelopes (robot frame).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.config import PredictSection, SafecaseConfig
from pipeline.frames import Pose, inverse
from pipeline.track.kalman import largest_std
from pipeline.types import (
    BoolArray,
    ConvexPolygons,
    Envelopes,
    FloatArray,
    FusedTracks,
    IntArray,
    Predictions,
    Tracks,
    TrackStatus,
)
from safety.geometry.envelopes import EnvelopeBuilder, grown_polygons
from safety.geometry.path import PathDistances
from safety.geometry.polygons import convex_polygons, transform_polygons
from safety.model.decision import GovernorInputs
from safety.model.monitors import MonitorVerdict
from safety.model.stopping import StoppingParams

__all__ = [
    "OBJECT_SPEED_WATCH",
    "bodies_now",
    "faster_than_the_domain",
    "governor_rows",
    "pedestrian_regions",
    "stack_polygons",
    "with_columns",
]


# The name the operating-domain check on object speed records its STOPs under (assumption A-4).
OBJECT_SPEED_WATCH = "domain:object_speed"


def stack_polygons(a: ConvexPolygons, b: ConvexPolygons) -> ConvexPolygons:
    """The polygons of ``a`` followed by those of ``b``."""
    if b.n == 0:
        return a
    if a.n == 0:
        return b
    lists = [a.vertex_list(i) for i in range(a.n)] + [b.vertex_list(i) for i in range(b.n)]
    return convex_polygons(lists)


def with_columns(base: ConvexPolygons, idx: IntArray, other: ConvexPolygons) -> ConvexPolygons:
    """``base`` with polygons ``idx`` replaced by those of ``other`` (in order)."""
    k = max(base.k, other.k)
    verts = base.padded_vertices(k)
    verts[:, :, idx] = other.padded_vertices(k)
    counts, slack = base.counts.copy(), base.slack_m.copy()
    counts[idx], slack[idx] = other.counts, other.slack_m
    return ConvexPolygons(vertices_m=verts, counts=counts, slack_m=slack)


def faster_than_the_domain(
    tracks: Tracks, predict_section: PredictSection, on_map: BoolArray | None = None
) -> MonitorVerdict | None:
    """STOP when a confirmed track is certainly faster (speed minus ``velocity_sigmas``
    sigmas) than ``predict.max_object_speed_mps``: the predictions assume no such object.
    Tracks ``on_map`` (last updated by a cluster lying wholly on the site's map,
    :class:`safety.bodies.OnMapMemory`) were last seen as the fixed structure and are not
    checked."""
    pc = predict_section
    speed = np.hypot(tracks.state[:, 2], tracks.state[:, 3])
    low = speed - pc.velocity_sigmas * largest_std(tracks.covariance[:, 2:, 2:])
    fast = (tracks.status == int(TrackStatus.CONFIRMED)) & (low > pc.max_object_speed_mps)
    if on_map is not None:
        fast &= ~on_map
    if not fast.any():
        return None
    i = int(np.flatnonzero(fast)[np.argmax(low[fast])])
    return MonitorVerdict.stop(
        OBJECT_SPEED_WATCH,
        f"track {int(tracks.track_id[i])} moves at {speed[i]:.2f} m/s (at least "
        f"{low[i]:.2f}), above predict.max_object_speed_mps = {pc.max_object_speed_mps}: "
        "outside the operating domain the predictions assume",
    )


def pedestrian_regions(
    now_s: float,
    fused: FusedTracks,
    robot_now: Pose,
    config: SafecaseConfig,
    params: StoppingParams,
    envelopes: EnvelopeBuilder,
) -> tuple[ConvexPolygons, ConvexPolygons]:
    """Thermal-only pedestrians: bodies now (tracking frame; a disc grown by the walking
    speed over the detection's age) and envelopes over the horizon (robot frame)."""
    p = params
    age = np.maximum(now_s - fused.pedestrian_stamp_s, 0.0)
    walk = float(p.person_speed_mps)
    radius = config.runtime.person_radius_m + walk * age
    centre = np.stack([fused.pedestrian_x_m, fused.pedestrian_y_m], axis=1)[:, None, :]
    sides = config.predict.disc_sides
    zones = grown_polygons(centre, radius, sides)
    # A thermal-only pedestrian is never a forklift near reversal.
    margin, _ = envelopes.margins(fused.pedestrian_confidence, False)
    reach = radius + walk * config.predict.horizon_s + margin
    env = grown_polygons(centre, reach, sides)
    env = transform_polygons(env, *inverse(robot_now))
    return zones, env


def bodies_now(pred: Predictions, tracks: Tracks, rows: BoolArray, sides: int) -> ConvexPolygons:
    """Body discs of prediction ``rows`` at the tracks' current positions."""
    row = np.searchsorted(tracks.track_id, pred.track_id[rows])
    centre = tracks.state[row, None, :2]
    return grown_polygons(centre, pred.body_radius_m[rows], sides)


def governor_rows(
    now_s: float,
    env: Envelopes,
    fused: FusedTracks,
    free_m: FloatArray,
    ped_free_m: FloatArray,
    dist: PathDistances,
    params: StoppingParams,
    loose_points: str,
) -> GovernorInputs:
    """One governor row per prediction row, pedestrian, loose point and the path's end."""
    p = params
    worst = float(p.worst_closing_speed_mps)
    loose_closing = float(p.static_speed_mps) if loose_points == "static" else worst
    n_ped = fused.n_pedestrians
    # (free distance, closing speed, confidence, near-reversal) per group of rows
    groups: list[tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike, npt.ArrayLike]] = [
        (free_m, env.closing_speed_mps, env.confidence, env.near_reversal),
        (
            ped_free_m,
            np.full(n_ped, float(p.person_speed_mps)),
            fused.pedestrian_confidence,
            np.zeros(n_ped, dtype=bool),
        ),
        ([dist.lookahead_m], [worst], [0.0], [False]),
    ]
    if dist.n_points_on_path:
        groups.append(([dist.point_free_m], [loose_closing], [0.0], [False]))

    # Every group's column already has its dtype (float64, or bool for the flags), so the
    # concatenations keep it.
    def column(k: int) -> npt.NDArray[Any]:
        return np.concatenate([g[k] for g in groups])

    return GovernorInputs(now_s, column(0), column(1), np.clip(column(2), 0.0, 1.0), column(3))
