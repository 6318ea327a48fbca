"""What the governor is given, function by function (SR-RUN-1, SR-RUN-2, SR-FUS-3).

The operating-domain check on object speed, the thermal-only pedestrians' regions and the
governor's rows were tested only through whole runtime cycles, where a boundary, a frame or a
column mix-up goes unseen. Here each at its limits: the speed check exactly at the domain's
bound and one float past it, confirmed tracks only, the velocity block of the covariance, the
fastest track named; a pedestrian's disc grown by the walking speed over the detection's age
(never shrunk by a stamp from the future) and its envelope in the robot frame; one governor row
per zone, pedestrian, the path's end and the nearest loose point, in that order, with their
closing speeds and clipped confidences.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

from pipeline.config import default_config
from pipeline.frames import Pose, to_child
from pipeline.types import (
    BoolArray,
    ConvexPolygons,
    Envelopes,
    FloatArray,
    FusedTracks,
    FusionCounts,
    Tracks,
    TrackStatus,
)
from properties.fusion_cases import make_tracks
from safety.geometry.envelopes import ROUNDING_M, EnvelopeBuilder, grown_polygons
from safety.geometry.path import PathDistances
from safety.geometry.polygons import no_polygons
from safety.model.stopping import StoppingParams
from safety.obstacles import (
    OBJECT_SPEED_WATCH,
    faster_than_the_domain,
    governor_rows,
    pedestrian_regions,
    stack_polygons,
)

OBSTACLES = ["safety/obstacles.py"]
CONFIG = default_config()
PS = CONFIG.predict
PARAMS = StoppingParams.from_config(CONFIG)
BUILDER = EnvelopeBuilder(PS, PARAMS)
SIDES = PS.disc_sides


def _moving(vxy: list[tuple[float, float]], sigma_v: float, sigma_p: float = 0.05) -> Tracks:
    """Confirmed tracks with velocities ``vxy`` [m/s], velocity sigma ``sigma_v`` and position
    sigma ``sigma_p`` (isotropic)."""
    n = len(vxy)
    tracks = make_tracks(0.0, np.zeros((n, 2)), np.array(vxy, dtype=float))
    cov = np.tile(np.diag([sigma_p**2, sigma_p**2, sigma_v**2, sigma_v**2]), (n, 1, 1))
    return replace(tracks, track_id=np.arange(3, 3 + n), covariance=cov)


@pytest.mark.requirement("SR-RUN-2", kind="example", code=OBSTACLES)
def test_the_object_speed_check_stops_only_past_the_domain_s_bound() -> None:
    """A track whose speed less K velocity sigmas is exactly the domain's bound is inside it;
    one float faster is outside, along x or y alike."""
    k, top = PS.velocity_sigmas, PS.max_object_speed_mps
    at = top + k * 0.25  # exact in binary floating point for the defaults
    assert at - k * 0.25 == top
    assert faster_than_the_domain(_moving([(at, 0.0)], 0.25), PS) is None
    past = math.nextafter(at, math.inf)
    for v in ((past, 0.0), (0.0, past), (0.0, -past)):
        verdict = faster_than_the_domain(_moving([v], 0.25), PS)
        assert verdict is not None, v
        assert verdict.monitor == OBJECT_SPEED_WATCH
        assert verdict.speed_limit_mps == 0.0


@pytest.mark.requirement("SR-RUN-2", kind="example", code=OBSTACLES)
def test_the_object_speed_check_reads_the_velocity_sigma_of_confirmed_tracks() -> None:
    """The velocity block of the covariance is what the speed is lowered by (a large position
    sigma changes nothing; a large velocity sigma keeps a fast track inside); a tentative or
    lost track is not checked; a track on the map is not either, and a slow one off the map
    stays inside."""
    fast = 0.5 + PS.max_object_speed_mps
    assert faster_than_the_domain(_moving([(fast, 0.0)], 0.1, sigma_p=5.0), PS) is not None
    assert faster_than_the_domain(_moving([(fast, 0.0)], 1.0, sigma_p=0.01), PS) is None
    for status in (TrackStatus.TENTATIVE, TrackStatus.LOST, TrackStatus.DORMANT):
        one = replace(_moving([(fast, 0.0)], 0.1), status=np.array([int(status)]))
        assert faster_than_the_domain(one, PS) is None, status
    two = _moving([(fast, 0.0), (0.0, fast)], 0.1)
    assert faster_than_the_domain(two, PS, np.array([True, True])) is None
    slow = _moving([(0.1, 0.0), (0.0, -0.2)], 0.1)
    assert faster_than_the_domain(slow, PS, np.array([False, False])) is None
    verdict = faster_than_the_domain(two, PS, np.array([True, False]))
    assert verdict is not None
    assert "track 4 " in verdict.reason


@pytest.mark.requirement("SR-RUN-2", kind="example", code=OBSTACLES)
def test_the_object_speed_verdict_names_the_fastest_track_and_its_speeds() -> None:
    """Of three tracks beyond the bound, the one whose speed less K sigma is largest is named,
    with its speed and that lower bound."""
    top = PS.max_object_speed_mps
    tracks = _moving([(top + 1.0, 0.0), (0.0, top + 2.0), (top + 1.5, 0.0)], 0.1)
    verdict = faster_than_the_domain(tracks, PS)
    assert verdict is not None
    low = top + 2.0 - PS.velocity_sigmas * 0.1
    assert verdict.reason == (
        f"track 4 moves at {top + 2.0:.2f} m/s (at least {low:.2f}), above "
        f"predict.max_object_speed_mps = {top}: outside the operating domain the predictions "
        "assume"
    )


def _fused(stamps_s: list[float], xy_m: list[tuple[float, float]], conf: float) -> FusedTracks:
    """No tracks; thermal-only pedestrians at ``xy_m`` (tracking frame) detected at
    ``stamps_s``, each with confidence ``conf``."""
    n = len(stamps_s)
    xy = np.array(xy_m, dtype=float).reshape(n, 2)
    return FusedTracks(
        stamp_s=0.0,
        tracks=make_tracks(0.0, np.zeros((0, 2))),
        confidence=np.zeros(0),
        thermal_index=np.zeros(0, dtype=np.int64),
        radar_index=np.zeros(0, dtype=np.int64),
        pedestrian_x_m=xy[:, 0],
        pedestrian_y_m=xy[:, 1],
        pedestrian_stamp_s=np.array(stamps_s, dtype=float),
        pedestrian_confidence=np.full(n, conf),
        pedestrian_index=np.arange(n),
        counts=FusionCounts(),
    )


def _disc_of(
    polygons: ConvexPolygons, j: int, centre: tuple[float, float], radius_m: float
) -> None:
    """Polygon ``j`` holds the disc of ``radius_m`` about ``centre`` and no more than the disc
    grown to its circumscribed polygon (plus rounding)."""
    ring = shapely.Polygon(polygons.vertices_m[:, : int(polygons.counts[j]), j].T)
    point = shapely.Point(*centre)
    assert ring.contains(point)
    assert ring.exterior.distance(point) >= radius_m - 1e-9
    outer = (radius_m + ROUNDING_M) / math.cos(math.pi / SIDES)
    assert ring.hausdorff_distance(point) <= outer + 1e-9


@pytest.mark.requirement("SR-FUS-3", kind="example", code=OBSTACLES)
@pytest.mark.parametrize("conf", [0.2, 0.95])
def test_a_pedestrian_s_disc_grows_with_the_detection_s_age_and_never_shrinks(conf: float) -> None:
    """Detections 0.3 s old, fresh and stamped 0.2 s in the future: discs of the person's radius
    plus the walking speed times the age (0 for the future one); envelopes over the horizon
    with the margin of their confidence (a low one and a high one, whose tier's margin is below
    the near-reversal tier's), in the frame of the robot at ``robot``."""
    robot: Pose = (1.0, -2.0, 0.7)
    now = 100.0
    person, walk = CONFIG.runtime.person_radius_m, float(PARAMS.person_speed_mps)
    fused = _fused([now - 0.3, now, now + 0.2], [(5.0, 2.0), (-3.0, 1.0), (0.0, 7.0)], conf)
    zones, env = pedestrian_regions(now, fused, robot, CONFIG, PARAMS, BUILDER)
    assert zones.n == env.n == 3
    margin = float(BUILDER.margins(np.array([conf]), np.array([False]))[0][0])
    assert margin > 0.0
    if conf > 0.9:
        assert margin < float(BUILDER.margins(np.array([conf]), np.array([True]))[0][0])
    for j, (age, xy) in enumerate(((0.3, (5.0, 2.0)), (0.0, (-3.0, 1.0)), (0.0, (0.0, 7.0)))):
        radius = person + walk * age
        _disc_of(zones, j, xy, radius)
        cx, cy = to_child(robot, np.array([xy[0]]), np.array([xy[1]]))
        reach = radius + walk * PS.horizon_s + margin
        _disc_of(env, j, (float(cx[0]), float(cy[0])), reach)


@pytest.mark.requirement("SR-FUS-3", kind="example", code=OBSTACLES)
def test_no_pedestrian_gives_no_region() -> None:
    zones, env = pedestrian_regions(
        5.0, _fused([], [], 0.2), (0.0, 0.0, 0.0), CONFIG, PARAMS, BUILDER
    )
    for regions in (zones, env):
        assert regions.n == 0
        np.testing.assert_array_equal(regions.vertices_m, no_polygons().vertices_m)


def _envelopes_for(n: int) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Closing speeds, confidences (one above 1 and one below 0, to be clipped) and
    near-reversal flags of ``n`` zones."""
    closing = np.linspace(0.5, 2.0, n)
    conf = np.array([1.4, -0.2, 0.6][:n])
    near = np.array([False, True, False][:n])
    return closing, conf, near


@pytest.mark.requirement("SR-RUN-1", kind="example", code=OBSTACLES)
@pytest.mark.parametrize("loose", ["static", "worst"])
@pytest.mark.parametrize("on_path", [0, 4])
def test_the_governor_gets_one_row_per_zone_pedestrian_path_end_and_loose_point(
    loose: str, on_path: int
) -> None:
    """Rows in order: every zone (its free distance, closing speed, clipped confidence,
    near-reversal flag), every pedestrian (the walking speed, its confidence), the path's end
    (the worst closing speed) and, when loose points lie on the path, the nearest of them (the
    static or the worst closing speed as configured)."""
    closing, conf, near = _envelopes_for(3)
    poly = grown_polygons(np.zeros((3, 1, 2)), np.full(3, 0.3), SIDES)
    env = Envelopes(
        stamp_s=1.0,
        polygons=poly,
        track_id=np.arange(3),
        mode=np.zeros(3, dtype=np.int64),
        class_index=np.zeros(3, dtype=np.int64),
        tier=np.zeros(3, dtype=np.int64),
        margin_m=np.full(3, 0.2),
        closing_speed_mps=closing,
        confidence=conf,
        near_reversal=near,
    )
    fused = _fused([1.0, 1.0], [(1.0, 1.0), (2.0, 2.0)], 0.25)
    dist = PathDistances(
        zone_free_m=np.array([1.0, 2.0, 3.0]),
        zone_hit=np.ones(3, dtype=bool),
        point_free_m=2.5,
        n_points_on_path=on_path,
        lookahead_m=6.0,
    )
    rows = governor_rows(
        7.0, env, fused, np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0]), dist, PARAMS, loose
    )
    worst = float(PARAMS.worst_closing_speed_mps)
    walk = float(PARAMS.person_speed_mps)
    free = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    speed = [*closing.tolist(), walk, walk, worst]
    confidence = [1.0, 0.0, 0.6, 0.25, 0.25, 0.0]
    flags = [False, True, False, False, False, False]
    if on_path:
        free.append(2.5)
        speed.append(float(PARAMS.static_speed_mps) if loose == "static" else worst)
        confidence.append(0.0)
        flags.append(False)
    assert rows.stamp_s == 7.0
    assert rows.free_distance_m.dtype == np.float64
    assert rows.free_distance_m.tolist() == free
    assert rows.closing_speed_mps is not None
    assert rows.closing_speed_mps.dtype == np.float64
    assert rows.closing_speed_mps.tolist() == speed
    assert rows.confidence is not None
    assert rows.confidence.dtype == np.float64
    assert rows.confidence.tolist() == confidence
    assert rows.near_reversal is not None
    assert rows.near_reversal.dtype == np.bool_
    assert rows.near_reversal.tolist() == flags


@pytest.mark.requirement("SR-RUN-1", kind="example", code=OBSTACLES)
def test_stacked_polygons_keep_both_sets_in_order() -> None:
    a = grown_polygons(np.array([[[0.0, 0.0]], [[5.0, 0.0]]]), np.array([0.5, 0.7]), SIDES)
    b = grown_polygons(np.array([[[0.0, 9.0]]]), np.array([1.0]), SIDES)
    none = grown_polygons(np.zeros((0, 1, 2)), np.zeros(0), SIDES)
    assert stack_polygons(a, none) is a
    assert stack_polygons(none, b) is b
    both = stack_polygons(a, b)
    assert both.n == 3
    for j, (src, i) in enumerate(((a, 0), (a, 1), (b, 0))):
        want = shapely.Polygon(src.vertices_m[:, : int(src.counts[i]), i].T)
        got = shapely.Polygon(both.vertices_m[:, : int(both.counts[j]), j].T)
        assert got.hausdorff_distance(want) < 1e-12, j
