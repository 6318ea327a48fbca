"""Convex geometry and swept-path collision: explicit examples and the hard-case corpus."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from evidence.record import Recorder
from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.errors import ConfigError, SafecaseError
from pipeline.types import ConvexPolygons
from properties.geometry_cases import HARD_CASES, HardCase
from properties.oracles.geometry import exact_pair, fcl_collide, z3_common_point
from safety.geometry.contact import contact_pairs
from safety.geometry.polygons import (
    DegeneratePolygonError,
    GeometryError,
    NonFiniteGeometryError,
    convex_polygons,
    transform_polygons,
)
from safety.geometry.sat import RHO, SatChecker
from safety.geometry.swept import (
    SweptPathChecker,
    Trajectories,
    rectangle_footprint,
    swept_hulls,
    unicycle_trajectories,
)

SAT = ["safety/geometry/sat.py", "safety/geometry/polygons.py"]


def _box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def _pair(a: np.ndarray, b: np.ndarray) -> tuple[ConvexPolygons, ConvexPolygons]:
    polys = convex_polygons([a, b])
    return polys.take([0]), polys.take([1])


# -------------------------------------------------------------------- the hard cases
@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize("case", HARD_CASES, ids=[c.name for c in HARD_CASES])
def test_hard_case(case: HardCase, evidence: Recorder, safecase_config: SafecaseConfig) -> None:
    tol = safecase_config.geometry.contact_tolerance_m
    a, b = _pair(case.a, case.b)
    va, vb = a.vertex_list(0), b.vertex_list(0)
    ours = bool(SatChecker(tol).overlap_pairs(a, b)[0])
    exact = exact_pair(va, vb)
    smt = z3_common_point(va, vb)
    assert exact.overlap == smt.common_point, "the two exact oracles disagree"
    assert exact.overlap == (case.exact in ("overlap", "touch")), case.exact
    evidence.counts(
        "verdicts",
        {
            "exact overlap": int(exact.overlap),
            "ours collision": int(ours),
            "shapely intersects": int(shapely.intersects(shapely.Polygon(va), shapely.Polygon(vb))),
            "fcl collide": int(fcl_collide(va, vb)),  # counted again below, by kind
        },
    )
    fcl_says = bool(fcl_collide(va, vb))
    if fcl_says != exact.overlap:
        kind = "FCL missed an exact contact" if exact.overlap else "FCL collision, exact clear"
        evidence.count("FCL disagreements (resolved by exact arithmetic)", kind)
        evidence.count(
            "FCL disagreements (resolved by exact arithmetic)",
            "SAT agreed with exact" if ours == exact.overlap else "SAT in tolerance band",
        )
    if not ours:
        # The safety-relevant claim, proved: no point lies in both polygons.
        evidence.smt(
            f"{case.name}: clear",
            "PROVED" if not smt.common_point else "REFUTED",
            smt.smtlib,
            model=smt.model,
            solver=smt.solver,
            time_s=smt.time_s,
            statement="SAT said clear: there is no (x, y) inside both closed polygons",
        )
    if exact.overlap:
        assert ours, f"{case.name}: SAT says clear but the polygons share a point"
    band = tol + RHO * max(np.abs(va).max(), np.abs(vb).max()) + float(a.slack_m[0] + b.slack_m[0])
    if not exact.overlap and exact.margin_m() > 2 * band:
        assert not ours, f"{case.name}: collision outside the tolerance band"
    if ours and not exact.overlap:
        evidence.note(
            f"{case.name}: collision within the tolerance band ({exact.margin_m():.3g} m)"
        )


# ----------------------------------------------------------------------- bad input
@pytest.mark.requirement("SR-SAT-4", kind="example", code=["safety/geometry/polygons.py"])
@pytest.mark.parametrize(
    ("points", "error", "words"),
    [
        ([[0, 0], [math.nan, 0], [0, 1]], NonFiniteGeometryError, "nan"),
        ([[0, 0], [math.inf, 0], [0, 1]], NonFiniteGeometryError, "inf"),
        ([[0, 0], [2e6, 0], [0, 1]], NonFiniteGeometryError, "2000000.0"),
        ([[0, 0], [1, 0]], DegeneratePolygonError, "2 point"),
        ([[1, 1], [1, 1], [1, 1]], DegeneratePolygonError, "coincide"),
        ([[0, 0], [1, 1], [0, 0], [1, 1]], DegeneratePolygonError, "collinear"),
        ([[0, 0], [1, 1], [2, 2], [3, 3]], DegeneratePolygonError, "collinear"),
    ],
)
def test_malformed_polygons_raise(points: list[list[float]], error: type, words: str) -> None:
    with pytest.raises(error, match=words) as info:
        convex_polygons([np.array(points, dtype=np.float64)])
    assert isinstance(info.value, SafecaseError)
    assert "polygon 0" in str(info.value)


@pytest.mark.requirement(
    "SR-SAT-4", kind="example", code=["safety/geometry/swept.py", "pipeline/types/"]
)
def test_malformed_poses_and_inputs_raise() -> None:
    theta = np.zeros((5, 2))
    theta[3, 1] = math.nan
    with pytest.raises(NonFiniteGeometryError, match=r"theta_rad\[3, 1\]"):
        Trajectories(np.zeros((5, 2)), np.zeros((5, 2)), theta, 0.1)
    with pytest.raises(NonFiniteGeometryError, match="not finite"):
        ConvexPolygons(np.full((2, 3, 1), math.nan), np.array([3]), np.zeros(1))
    with pytest.raises(GeometryError, match="ConvexPolygons"):
        SatChecker().overlap_pairs(_box(0, 0, 1, 1), _box(0, 0, 1, 1))  # type: ignore[arg-type]
    with pytest.raises(GeometryError, match="tolerance_m"):
        SatChecker(math.nan)
    config = overridden(default_config(), {"geometry": {"max_obstacles": 2}}).geometry
    obstacles = convex_polygons([_box(i, 5, i + 1, 6) for i in range(3)])
    traj = unicycle_trajectories([1.0], [0.0], horizon_s=1.0, step_s=0.1)
    with pytest.raises(GeometryError, match="max_obstacles"):
        SweptPathChecker(config).check(rectangle_footprint(0.7, 0.5), traj, obstacles)


@pytest.mark.requirement("SR-CFG-1", kind="example")
def test_geometry_grid_must_match_trajectory_count() -> None:
    with pytest.raises(ConfigError, match="n_trajectories"):
        overridden(default_config(), {"geometry": {"n_speeds": 5}})


# --------------------------------------------------------------------- normalisation
@pytest.mark.requirement("SR-SAT-1", kind="example", code=["safety/geometry/polygons.py"])
def test_normalisation_orders_and_cleans() -> None:
    clockwise = np.array([[0, 0], [0, 1], [1, 1], [1, 0], [1, 0], [0.5, 0]], dtype=np.float64)
    poly = convex_polygons([clockwise])
    vertices = poly.vertex_list(0)
    assert len(vertices) == 4  # the duplicate and the collinear midpoint are gone
    x, y = vertices[:, 0], vertices[:, 1]
    assert 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)) == pytest.approx(1.0)
    assert (vertices[0] == [0, 0]).all()


# -------------------------------------------------------------- contact: depth, MTV
@pytest.mark.requirement("SR-SAT-2", kind="example", code=["safety/geometry/contact.py"])
def test_penetration_mtv_and_distance() -> None:
    a, b = _pair(_box(0, 0, 1, 1), _box(0.7, 0.2, 1.7, 0.8))
    contact = contact_pairs(a, b)
    assert contact.depth_m[0] == pytest.approx(0.3)
    assert contact.mtv_m[0] == pytest.approx([0.3, 0.0])
    moved = transform_polygons(b, contact.mtv_m[0, 0] + 1e-9, 0.0, 0.0)
    assert not SatChecker(0.0).overlap_pairs(a, moved)[0]
    a, b = _pair(_box(0, 0, 1, 1), _box(4, 5, 5, 6))
    contact = contact_pairs(a, b)
    assert contact.distance_m[0] == pytest.approx(5.0)
    assert contact.depth_m[0] == 0.0


# ------------------------------------------------------------------- planner check
@pytest.mark.requirement("SR-SAT-3", kind="example", code=["safety/geometry/swept.py"])
def test_swept_path_check_reports_obstacle_and_time(evidence: Recorder) -> None:
    config = default_config().geometry
    footprint = rectangle_footprint(0.7, 0.5)
    # Straight ahead at 1 m/s and a hard left turn; a box 1.0 m ahead of the nose.
    traj = unicycle_trajectories([1.0, 1.0], [0.0, 1.0], horizon_s=1.5, step_s=0.1)
    obstacles = convex_polygons(
        [_box(1.35, -0.3, 1.6, 0.3), _box(60.0, 0.0, 61.0, 1.0), _box(-1.0, 3.0, 0.0, 3.5)]
    )
    report = SweptPathChecker(config).check(footprint, traj, obstacles)
    assert report.blocked[0].tolist() == [True, False, False]
    assert report.gated.tolist() == [False, True, False]
    # The nose (x = 0.35 m) reaches 1.35 m after 1.0 s: the segment [0.9 s, 1.0 s] touches.
    assert report.contact_step[0, 0] == 9
    assert report.earliest_contact_s[0] == pytest.approx(0.9)
    assert report.first_obstacle[0] == 0
    assert not report.hull_only[0, 0]
    evidence.note(f"straight path blocked by envelope 0 at {report.earliest_contact_s[0]:.1f} s")


@pytest.mark.requirement("SR-SAT-3", kind="example", code=["safety/geometry/swept.py"])
def test_hull_only_block_is_reported_as_contact_now() -> None:
    footprint = rectangle_footprint(0.4, 0.4)
    # A half circle of radius 2 m: the hull covers the centre, the footprints never do.
    traj = unicycle_trajectories([2.0], [1.0], horizon_s=math.pi, step_s=0.1)
    obstacles = convex_polygons([_box(-0.1, 1.9, 0.1, 2.1)])
    report = SweptPathChecker(default_config().geometry).check(footprint, traj, obstacles)
    assert report.blocked[0, 0]
    assert report.hull_only[0, 0]
    assert report.contact_step[0, 0] == 0
    assert report.earliest_contact_s[0] == 0.0


@pytest.mark.requirement("SR-SAT-3", kind="example", code=["safety/geometry/swept.py"])
def test_swept_hull_of_straight_motion_is_a_rectangle() -> None:
    traj = unicycle_trajectories([1.0], [0.0], horizon_s=1.5, step_s=0.1)
    hull = swept_hulls(rectangle_footprint(0.7, 0.5), traj)
    assert hull.counts[0] == 4
    vertices = hull.vertex_list(0)
    assert vertices[:, 0].min() == pytest.approx(-0.35)
    assert vertices[:, 0].max() == pytest.approx(1.85)


@pytest.mark.requirement("SR-SAT-3", kind="example", code=["safety/geometry/swept.py"])
def test_configured_candidates_and_footprint() -> None:
    checker = SweptPathChecker(default_config().geometry)
    traj = checker.candidates(max_speed_mps=1.0)
    assert traj.n == 175
    assert traj.steps == 16
    assert traj.step_s == pytest.approx(0.1)
    hull = swept_hulls(checker.footprint(), traj)
    assert hull.n == 175
