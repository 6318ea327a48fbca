"""Swept hulls, the planner's swept-path check and malformed input (SR-SAT-3, SR-SAT-4)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.config import SafecaseConfig
from pipeline.errors import GeometryError
from pipeline.frames import to_parent
from pipeline.types import ConvexPolygons
from properties.geometry_cases import convex_points
from properties.oracles.geometry import exact_point_outside_sq, shapely_polygons
from safety.geometry.polygons import convex_polygons
from safety.geometry.swept import SweptPathChecker, Trajectories, swept_hulls, unicycle_trajectories

_speeds = st.lists(st.floats(0.0, 2.0), min_size=1, max_size=6)


@st.composite
def _trajectories(draw: st.DrawFn) -> Trajectories:
    n = draw(st.integers(1, 6), label="trajectories")
    v = draw(st.lists(st.floats(0.0, 2.0), min_size=n, max_size=n), label="speeds")
    w = draw(st.lists(st.floats(-2.0, 2.0), min_size=n, max_size=n), label="yaw rates")
    start = draw(st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-4, 4)))
    horizon = draw(st.sampled_from([0.1, 0.5, 1.5, 3.0]), label="horizon")
    return unicycle_trajectories(
        v, w, horizon_s=horizon, step_s=0.1, x0_m=start[0], y0_m=start[1], theta0_rad=start[2]
    )


@st.composite
def _footprint(draw: st.DrawFn) -> ConvexPolygons:
    pts = draw(convex_points(min_scale_exp=-0.7, max_scale_exp=0.3), label="footprint")
    return convex_polygons([pts - pts.mean(axis=0)])


@pytest.mark.requirement(
    "SR-SAT-3", kind="property", code=["safety/geometry/swept.py", "safety/geometry/polygons.py"]
)
@settings(max_examples=examples(60))
@given(footprint=_footprint(), traj=_trajectories())
def test_swept_hull_contains_every_footprint(footprint: ConvexPolygons, traj: Trajectories) -> None:
    hulls = swept_hulls(footprint, traj)
    f = footprint.vertex_list(0)
    rec = current()
    for t in range(traj.n):
        hull = hulls.vertex_list(t)
        slack_sq = Fraction(float(hulls.slack_m[t])) ** 2
        # Placed by the one rigid transform (rounding below the contact tolerance).
        pose = (traj.x_m[:, t, None], traj.y_m[:, t, None], traj.theta_rad[:, t, None])
        px, py = to_parent(pose, f[:, 0], f[:, 1])
        for x, y in zip(px.ravel(), py.ravel(), strict=True):
            outside = exact_point_outside_sq((float(x), float(y)), hull)
            assert outside <= slack_sq, f"footprint vertex ({x}, {y}) outside hull {t}"
            rec.count("footprint vertices", "inside (exact)" if outside == 0 else "within slack")
        # Counter-clockwise and convex: every turn is a left turn (up to rounding).
        e = np.roll(hull, -1, axis=0) - hull
        turn = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
        assert (turn > -1e-12 * np.abs(hull).max() ** 2).all()
    rec.count("hulls", "checked", traj.n)


@st.composite
def _obstacles(draw: st.DrawFn) -> ConvexPolygons:
    n = draw(st.integers(1, 8), label="envelopes")
    shapes = []
    for _ in range(n):
        pts = draw(convex_points(min_scale_exp=-1.0, max_scale_exp=0.3), label="envelope")
        at = draw(st.tuples(st.floats(-4, 4), st.floats(-4, 4)), label="at")
        shapes.append(pts - pts.mean(axis=0) + np.asarray(at))
    return convex_polygons(shapes)


@pytest.mark.requirement("SR-SAT-3", kind="property", code=["safety/geometry/swept.py"])
@settings(max_examples=examples(60))
@given(footprint=_footprint(), obstacles=_obstacles(), data=st.data())
def test_swept_path_check_matches_geos(
    footprint: ConvexPolygons,
    obstacles: ConvexPolygons,
    data: st.DataObject,
    safecase_config: SafecaseConfig,
) -> None:
    v = data.draw(st.lists(st.floats(0.0, 2.0), min_size=1, max_size=8), label="speeds")
    w = data.draw(st.lists(st.floats(-2, 2), min_size=len(v), max_size=len(v)), label="yaw")
    traj = unicycle_trajectories(v, w, horizon_s=1.5, step_s=0.1)
    report = SweptPathChecker(safecase_config.geometry).check(footprint, traj, obstacles)
    hulls = shapely_polygons(swept_hulls(footprint, traj))
    envs = shapely_polygons(obstacles)
    geos = shapely.intersects(hulls[:, None], envs[None, :])
    rec = current()
    # Every GEOS intersection is blocked (zero misses); extra blocks only within the band.
    assert not (geos & ~report.blocked).any(), "a hull that intersects an envelope was clear"
    extra = report.blocked & ~geos
    if extra.any():
        gaps = shapely.distance(hulls[:, None], envs[None, :])[extra]
        assert (gaps <= 1e-6).all()
        rec.count("blocks", "within the tolerance band", int(extra.sum()))
    rec.count("blocks", "blocked pairs", int(report.blocked.sum()))
    rec.count("blocks", "clear pairs", int((~report.blocked).sum()))
    # The contact step is never later than the first sampled footprint that touches.
    f = footprint.vertex_list(0)
    for t, o in zip(*np.nonzero(report.blocked), strict=True):
        c, s = np.cos(traj.theta_rad[:, t]), np.sin(traj.theta_rad[:, t])
        fx = c[:, None] * f[:, 0] - s[:, None] * f[:, 1] + traj.x_m[:, t, None]
        fy = s[:, None] * f[:, 0] + c[:, None] * f[:, 1] + traj.y_m[:, t, None]
        feet = shapely.polygons(np.stack([fx, fy], axis=-1))
        touching = np.flatnonzero(shapely.intersects(feet, envs[o]))
        if touching.size:
            assert report.contact_step[t, o] <= touching[0]
            rec.count("contact step", "at or before the first touching footprint")
        else:
            rec.count("contact step", "no sampled footprint touches (between samples or hull)")
        if report.hull_only[t, o]:
            rec.count("contact step", "hull only (pocket of a curved path)")
    blocked = report.blocked.any(axis=1)
    assert np.isinf(report.earliest_contact_s[~blocked]).all()
    assert (report.first_obstacle[~blocked] == -1).all()
    assert (report.blocked[np.flatnonzero(blocked), report.first_obstacle[blocked]]).all()


@pytest.mark.requirement(
    "SR-SAT-4", kind="property", code=["safety/geometry/polygons.py", "safety/geometry/swept.py"]
)
@settings(max_examples=examples(100))
@given(
    pts=convex_points(),
    where=st.integers(0, 7),
    bad=st.sampled_from([math.nan, math.inf, -math.inf, 1e7, -1e300]),
    axis=st.integers(0, 1),
    target=st.sampled_from(["polygon", "pose"]),
)
def test_malformed_input_always_raises(
    pts: np.ndarray,
    where: int,
    bad: float,
    axis: int,
    target: str,
    safecase_config: SafecaseConfig,
) -> None:
    footprint = convex_polygons([np.array([[-0.3, -0.2], [0.3, -0.2], [0.3, 0.2], [-0.3, 0.2]])])
    traj = unicycle_trajectories([1.0, 0.5], [0.0, 0.3], horizon_s=1.0, step_s=0.1)
    checker = SweptPathChecker(safecase_config.geometry)
    good = convex_polygons([np.array([[2.0, 2.0], [3.0, 2.0], [3.0, 3.0], [2.0, 3.0]])])
    if target == "polygon":
        pts = pts.copy()
        pts[where % len(pts), axis] = bad
        with pytest.raises(GeometryError):
            checker.check(footprint, traj, convex_polygons([pts]))
    else:
        arrays = [traj.x_m.copy(), traj.y_m.copy(), traj.theta_rad.copy()]
        which = (axis + where) % 3
        # A finite heading of any size is a valid pose; a huge finite one becomes NaN.
        arrays[which][where % traj.steps, where % traj.n] = (
            math.nan if which == 2 and math.isfinite(bad) else bad
        )
        with pytest.raises(GeometryError):
            checker.check(footprint, Trajectories(arrays[0], arrays[1], arrays[2], 0.1), good)
    current().count("malformed inputs", f"{target}: raised GeometryError")
