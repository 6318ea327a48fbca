"""The swept-path check field by field: trajectories, candidates, segments, pre-gate (SR-SAT-3,
SR-SAT-4).

The mutation campaign (SR-EVD-5, SR-EVD-6; docs/findings/mutation.md) showed these unwatched:
the trajectory checks and their messages, the default candidate grid and its order, the
footprint's corners, segment hulls of one and two poses and of a turn, which call a hull
error names, the pre-gate around a robot away from the origin (and with no trajectory or no
envelope), the report of several blocked trajectories at once, a hull-only pair beside a
swept one, a contact at the first step, and the input checks of ``check``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.config import GeometrySection, default_config, overridden
from pipeline.errors import GeometryError
from pipeline.types import FloatArray
from safety.geometry.polygons import (
    NonFiniteGeometryError,
    PolygonBounds,
    Workspace,
    convex_polygons,
)
from safety.geometry.sat import RHO
from safety.geometry.swept import (
    SweptPathChecker,
    Trajectories,
    candidate_trajectories,
    rectangle_footprint,
    segment_hulls,
    swept_hulls,
    unicycle_trajectories,
)

SWEPT = ["safety/geometry/swept.py"]


def _geometry(**values: float) -> GeometrySection:
    return overridden(default_config(), {"geometry": values}).geometry


def _box(x0: float, y0: float, x1: float, y1: float) -> FloatArray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def _square(cx: float, cy: float, half: float = 0.1) -> FloatArray:
    return _box(cx - half, cy - half, cx + half, cy + half)


@pytest.mark.requirement("SR-SAT-4", kind="example", code=SWEPT)
def test_trajectories_refuse_bad_shapes_with_the_reason() -> None:
    z52, z53 = np.zeros((5, 2)), np.zeros((5, 3))
    z5 = np.zeros(5)
    for (x, y, theta), shapes in (
        ((z52, z53, z52), "(5, 2), (5, 3), (5, 2)"),
        ((z5, z5, z5), "(5,), (5,), (5,)"),
    ):
        with pytest.raises(GeometryError) as refused:
            Trajectories(x, y, theta, 0.1)
        assert str(refused.value) == (
            "Trajectories: x_m, y_m and theta_rad must be (S, N) arrays of one shape, got " + shapes
        )
    empty = np.zeros((0, 2))
    with pytest.raises(GeometryError) as refused:
        Trajectories(empty, empty, empty, 0.1)
    assert str(refused.value) == "Trajectories: at least one pose per trajectory is needed"
    one_pose = Trajectories(np.ones((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)), 0.1)
    assert (one_pose.steps, one_pose.n) == (1, 2)
    none = Trajectories(np.zeros((3, 0)), np.zeros((3, 0)), np.zeros((3, 0)), 0.1)
    assert (none.steps, none.n) == (3, 0)


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_the_default_candidate_grid_and_its_order() -> None:
    """7 speeds in (0, 1] m/s times 25 yaw rates in [-1, 1] rad/s over 1.5 s every 0.1 s;
    trajectory i * 25 + j has speed i and yaw rate j."""
    grid = candidate_trajectories()
    assert (grid.n, grid.steps, grid.step_s) == (175, 16, 0.1)
    final_yaw = grid.theta_rad[-1].reshape(7, 25)
    assert final_yaw[:, 0] == pytest.approx([-1.5] * 7)
    assert final_yaw[:, 24] == pytest.approx([1.5] * 7)
    assert final_yaw[0] == pytest.approx(np.linspace(-1.5, 1.5, 25))
    straight = grid.x_m[:, 12::25]  # yaw rate 0, the 7 speeds
    assert straight[-1] == pytest.approx(1.5 * np.arange(1, 8) / 7)
    assert straight[1] == pytest.approx(0.1 * np.arange(1, 8) / 7)


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_the_checker_builds_its_configured_candidates() -> None:
    config = _geometry(
        n_speeds=3,
        n_yaw_rates=5,
        n_trajectories=15,
        max_yaw_rate_radps=0.5,
        horizon_s=1.0,
        sample_dt_s=0.2,
    )
    built = SweptPathChecker(config).candidates(0.8)
    expected = candidate_trajectories(
        3, 5, max_speed_mps=0.8, max_yaw_rate_radps=0.5, horizon_s=1.0, step_s=0.2
    )
    assert (built.n, built.steps, built.step_s) == (15, 6, 0.2)
    for got, want in (
        (built.x_m, expected.x_m),
        (built.y_m, expected.y_m),
        (built.theta_rad, expected.theta_rad),
    ):
        assert np.array_equal(got, want)


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_the_rectangle_footprint_and_a_footprint_of_one_polygon() -> None:
    corners = rectangle_footprint(0.7, 0.5).vertex_list(0)
    assert sorted(map(tuple, corners.tolist())) == [
        (-0.35, -0.25),
        (-0.35, 0.25),
        (0.35, -0.25),
        (0.35, 0.25),
    ]
    two = convex_polygons([_square(0.0, 0.0), _square(1.0, 0.0)])
    traj = unicycle_trajectories([1.0], [0.0], horizon_s=0.5, step_s=0.1)
    with pytest.raises(GeometryError) as refused:
        swept_hulls(two, traj)
    assert str(refused.value) == "footprint: expected one polygon, got 2"


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_segment_hulls_of_one_and_two_poses_and_along_a_turn() -> None:
    footprint = rectangle_footprint(0.7, 0.5)
    still = unicycle_trajectories([1.0], [0.0], horizon_s=0.0, step_s=0.1)
    assert still.steps == 1
    alone = segment_hulls(footprint, still, np.array([0]))
    assert alone.n == 1
    assert sorted(map(tuple, alone.vertex_list(0).tolist())) == sorted(
        map(tuple, footprint.vertex_list(0).tolist())
    )
    step = unicycle_trajectories([1.0], [0.0], horizon_s=0.1, step_s=0.1)
    assert step.steps == 2
    one = segment_hulls(footprint, step, np.array([0]))
    assert one.n == 1
    assert one.vertex_list(0)[:, 0].max() == pytest.approx(0.45)
    turn = unicycle_trajectories([1.0, 0.5], [1.0, -2.0], horizon_s=1.0, step_s=0.1)
    segments = segment_hulls(footprint, turn, np.array([1, 0]))
    assert segments.n == 2 * 10
    for i, which in enumerate((1, 0)):
        for k in (0, 4, 9):
            pair = Trajectories(
                turn.x_m[k : k + 2, [which]],
                turn.y_m[k : k + 2, [which]],
                turn.theta_rad[k : k + 2, [which]],
                0.1,
            )
            want = swept_hulls(footprint, pair).vertex_list(0)
            got = segments.vertex_list(i * 10 + k)
            assert got.shape == want.shape
            assert got == pytest.approx(want, abs=1e-12), (which, k)


@pytest.mark.requirement("SR-SAT-4", kind="example", code=SWEPT)
def test_a_hull_beyond_the_coordinate_limit_names_the_trajectory_or_segment() -> None:
    """A pose 0.1 m inside the coordinate limit puts the footprint's nose past it."""
    footprint = rectangle_footprint(0.7, 0.5)
    edge = unicycle_trajectories(
        [1.0], [0.0], horizon_s=0.1, step_s=0.1, x0_m=1.0e6 - 0.2, y0_m=0.0
    )
    with pytest.raises(NonFiniteGeometryError, match=r"^trajectory 0: point \d+ is "):
        swept_hulls(footprint, edge)
    with pytest.raises(NonFiniteGeometryError, match=r"^segment 0: point \d+ is "):
        segment_hulls(footprint, edge, np.array([0]))


def _placed(direction: tuple[float, float], distance_m: float, radius_m: float) -> FloatArray:
    """A 0.2 m square whose bounding circle lies ``distance_m`` from the robot at (100, 50)."""
    ux, uy = direction
    norm = math.hypot(ux, uy)
    centre = distance_m + radius_m
    return _square(100.0 + centre * ux / norm, 50.0 + centre * uy / norm)


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_the_pregate_measures_from_the_robot_away_from_the_origin() -> None:
    """Robot at (100, 50) driving 2 m along +y; gate = the farthest hull vertex from the robot
    (`reach`, above pregate_m = 0.5 here) plus a margin of about 2 mm (twice the 1 mm contact
    tolerance). Envelopes beyond the gate in four directions are gated, those inside it not."""
    config = _geometry(pregate_m=0.5, contact_tolerance_m=1e-3)
    footprint = rectangle_footprint(0.7, 0.5)
    traj = unicycle_trajectories(
        [1.0], [0.0], horizon_s=2.0, step_s=0.1, x0_m=100.0, y0_m=50.0, theta0_rad=math.pi / 2
    )
    hull = swept_hulls(footprint, traj).vertex_list(0)
    reach = float(np.hypot(hull[:, 0] - 100.0, hull[:, 1] - 50.0).max())
    assert reach == pytest.approx(math.hypot(0.25, 2.35))
    radius = float(PolygonBounds(convex_polygons([_square(0.0, 0.0)])).radius_m[0])
    cases = [
        ((0.0, -1.0), reach + 0.5, True),  # straight behind
        ((-1.0, 0.0), reach - 0.2, False),  # to the left, within reach
        ((1.0, 0.0), reach + 0.1, True),  # to the right, just beyond
        ((-1.0, -1.0), reach + 1e-3, False),  # inside the margin
        ((1.0, -1.0), reach + 2.5e-3, True),  # just past the margin
    ]
    # The margin's rounding allowance, 1e-9 (1 + reach) beyond twice the SAT threshold (and
    # its rounding, RHO times the coordinates' magnitude): an envelope half of it beyond is
    # not gated, one 1.15 times it beyond is.
    twice_threshold = 2.0 * (1e-3 + RHO * float(np.abs(hull).max()))
    allowance = 1e-9 * (1.0 + reach)
    cases += [
        ((1.0, 0.0), reach + twice_threshold + 0.5 * allowance, False),
        ((1.0, 0.0), reach + twice_threshold + 1.15 * allowance, True),
    ]
    obstacles = convex_polygons([_placed(d, distance, radius) for d, distance, _ in cases])
    report = SweptPathChecker(config).check(
        footprint, traj, obstacles, robot_x_m=100.0, robot_y_m=50.0
    )
    assert report.gated.tolist() == [gated for _, _, gated in cases]
    assert not report.blocked.any()


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_the_pregate_with_no_trajectory_and_with_no_envelope() -> None:
    config = _geometry(pregate_m=0.5, contact_tolerance_m=1e-3)
    checker = SweptPathChecker(config)
    footprint = rectangle_footprint(0.7, 0.5)
    empty = Trajectories(np.zeros((16, 0)), np.zeros((16, 0)), np.zeros((16, 0)), 0.1)
    near = convex_polygons([_square(0.85, 0.0), _square(0.0, 0.4)])  # 0.75 m and 0.3 m away
    report = checker.check(footprint, empty, near)
    assert report.gated.tolist() == [True, False]  # no hull: the gate is pregate_m alone
    assert report.blocked.shape == (0, 2)
    traj = unicycle_trajectories([1.0], [0.0], horizon_s=1.0, step_s=0.1)
    clear = checker.check(footprint, traj, convex_polygons(np.zeros((0, 3, 2))))
    assert clear.blocked.shape == (1, 0)
    assert clear.gated.shape == (0,)
    assert clear.earliest_contact_s.tolist() == [math.inf]
    assert clear.first_obstacle.tolist() == [-1]


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_the_default_robot_position_is_the_origin() -> None:
    """Envelopes within reach of the origin, left and behind, are not gated; measured from a
    robot 1 m away they would be."""
    config = _geometry(pregate_m=0.5)
    footprint = rectangle_footprint(0.7, 0.5)
    traj = unicycle_trajectories([1.0], [0.0], horizon_s=2.0, step_s=0.1)
    obstacles = convex_polygons([_square(-2.1, 0.0), _square(0.0, -2.1)])
    report = SweptPathChecker(config).check(footprint, traj, obstacles)
    assert report.gated.tolist() == [False, False]
    moved = SweptPathChecker(config).check(footprint, traj, obstacles, robot_x_m=1.0, robot_y_m=1.0)
    assert moved.gated.tolist() == [True, True]


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_several_blocked_trajectories_a_hull_only_pair_and_a_contact_at_once() -> None:
    """Two straight paths (1 and 0.5 m/s) reach a box at x = 1.35 m (right of their centre
    line, clear of the turn) in segments 11 and 22; a
    half circle of radius 2 m only encloses a box at its centre (hull only: contact now); the
    pairs that do not touch keep contact step -1."""
    footprint = rectangle_footprint(0.4, 0.4)
    traj = unicycle_trajectories([1.0, 0.5, 2.0], [0.0, 0.0, 1.0], horizon_s=math.pi, step_s=0.1)
    obstacles = convex_polygons([_box(1.35, -0.3, 1.6, -0.1), _box(-0.1, 1.9, 0.1, 2.1)])
    report = SweptPathChecker(default_config().geometry).check(footprint, traj, obstacles)
    assert report.blocked.tolist() == [[True, False], [True, False], [False, True]]
    assert report.contact_step.tolist() == [[11, -1], [22, -1], [-1, 0]]
    assert report.hull_only.tolist() == [[False, False], [False, False], [False, True]]
    assert report.earliest_contact_s == pytest.approx([1.1, 2.2, 0.0])
    assert report.first_obstacle.tolist() == [0, 0, 1]
    assert report.step_s == 0.1


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_a_contact_at_the_first_step_is_not_hull_only() -> None:
    footprint = rectangle_footprint(0.4, 0.4)
    traj = unicycle_trajectories([1.0], [0.0], horizon_s=1.0, step_s=0.1)
    report = SweptPathChecker(default_config().geometry).check(
        footprint, traj, convex_polygons([_square(0.0, 0.0)])
    )
    assert report.contact_step.tolist() == [[0]]
    assert report.hull_only.tolist() == [[False]]
    assert report.earliest_contact_s.tolist() == [0.0]


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_a_single_pose_trajectory_is_checked_as_its_footprint() -> None:
    footprint = rectangle_footprint(0.4, 0.4)
    still = unicycle_trajectories([0.0, 0.0], [0.0, 0.0], horizon_s=0.0, step_s=0.1)
    moved = Trajectories(still.x_m + np.array([0.0, 5.0]), still.y_m, still.theta_rad, 0.1)
    report = SweptPathChecker(default_config().geometry).check(
        footprint, moved, convex_polygons([_square(0.25, 0.0), _square(5.0, 0.3)])
    )
    assert report.blocked.tolist() == [[True, False], [False, True]]
    assert report.contact_step.tolist() == [[0, -1], [-1, 0]]
    assert report.hull_only.tolist() == [[False, False], [False, False]]


@pytest.mark.requirement("SR-SAT-4", kind="example", code=SWEPT)
def test_check_refuses_too_many_envelopes_and_a_bad_robot_position() -> None:
    checker = SweptPathChecker(_geometry(max_obstacles=2))
    footprint = rectangle_footprint(0.4, 0.4)
    traj = unicycle_trajectories([1.0], [0.0], horizon_s=1.0, step_s=0.1)
    two = convex_polygons([_square(5.0, 5.0), _square(6.0, 5.0)])
    assert checker.check(footprint, traj, two).blocked.shape == (1, 2)  # at the limit
    for x, y in ((0.0, math.nan), (math.inf, 0.0)):
        with pytest.raises(NonFiniteGeometryError) as refused:
            checker.check(footprint, traj, two, robot_x_m=x, robot_y_m=y)
        assert str(refused.value) == (
            f"swept-path check: robot position ({x!r}, {y!r}) is not finite"
        )


@pytest.mark.requirement("SR-SAT-4", kind="example", code=SWEPT)
def test_each_pose_field_is_checked_and_named() -> None:
    """x_m and y_m must be finite and within the coordinate limit, theta_rad finite only (an
    angle of any size is a pose); the message names the field, the trajectory and the step."""
    ok = np.zeros((4, 2))
    for field, value, words in (
        ("x_m", math.nan, "nan"),
        ("y_m", math.inf, "inf"),
        ("x_m", 2.0e6, "2000000.0"),
        ("y_m", -2.0e6, "-2000000.0"),
        ("theta_rad", math.nan, "nan"),
    ):
        poses = {"x_m": ok.copy(), "y_m": ok.copy(), "theta_rad": ok.copy()}
        poses[field][2, 1] = value
        with pytest.raises(NonFiniteGeometryError) as refused:
            Trajectories(poses["x_m"], poses["y_m"], poses["theta_rad"], 0.1)
        assert str(refused.value) == (
            f"Trajectories: {field}[2, 1] = {words} (trajectory 1, step 2); expected a finite pose"
        )
    spun = ok.copy()
    spun[2, 1] = 2.0e6
    assert Trajectories(ok, ok, spun, 0.1).theta_rad[2, 1] == 2.0e6
    at_limit = np.full((4, 2), 1.0e6)
    assert Trajectories(at_limit, -at_limit, ok, 0.1).x_m[0, 0] == 1.0e6
    for step in (0.0, -0.1, math.inf, math.nan):
        with pytest.raises(GeometryError) as bad_step:
            Trajectories(ok, ok, ok, step)
        assert str(bad_step.value) == f"Trajectories: step_s = {step!r}; expected > 0"


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_the_hull_functions_use_the_workspace_they_are_given() -> None:
    """Scratch comes from the caller's buffers (no fresh allocation per cycle)."""
    footprint = rectangle_footprint(0.7, 0.5)
    traj = unicycle_trajectories([1.0, 0.5], [0.0, 1.0], horizon_s=1.0, step_s=0.1)
    hull_ws, segment_ws = Workspace(), Workspace()
    assert (hull_ws.nbytes, segment_ws.nbytes) == (0, 0)
    swept_hulls(footprint, traj, hull_ws)
    segment_hulls(footprint, traj, np.array([0, 1]), segment_ws)
    assert hull_ws.nbytes > 0
    assert segment_ws.nbytes > 0


@pytest.mark.requirement("SR-SAT-3", kind="example", code=SWEPT)
def test_a_constant_arc_lies_on_its_circle() -> None:
    """At 1 m/s and 1 rad/s the pose after t seconds is (sin t, 1 - cos t, t) exactly (radius
    1 m about (0, 1)); at 2 m/s and -0.5 rad/s it is (4 sin(t / 2), -4 (1 - cos(t / 2)))."""
    arcs = unicycle_trajectories([1.0, 2.0], [1.0, -0.5], horizon_s=3.0, step_s=0.5)
    t = np.arange(7) * 0.5
    assert arcs.x_m[:, 0] == pytest.approx(np.sin(t), abs=1e-12)
    assert arcs.y_m[:, 0] == pytest.approx(1.0 - np.cos(t), abs=1e-12)
    assert arcs.theta_rad[:, 0] == pytest.approx(t, abs=1e-12)
    assert arcs.x_m[:, 1] == pytest.approx(4.0 * np.sin(t / 2), abs=1e-12)
    assert arcs.y_m[:, 1] == pytest.approx(-4.0 * (1.0 - np.cos(t / 2)), abs=1e-12)


@pytest.mark.requirement("SR-SAT-4", kind="example", code=SWEPT)
def test_unicycle_trajectories_refuse_bad_grids_with_the_reason() -> None:
    for speeds, rates, shapes in (
        ([1.0, 2.0], [0.0], "(2,) and yaw rates (1,)"),
        ([[1.0]], [[0.0]], "(1, 1) and yaw rates (1, 1)"),
    ):
        with pytest.raises(GeometryError) as refused:
            unicycle_trajectories(speeds, rates, horizon_s=1.0, step_s=0.1)
        assert str(refused.value) == f"unicycle_trajectories: speeds {shapes}"
    for horizon, step in (
        (-1.0, 0.1),
        (math.inf, 0.1),
        (math.nan, 0.1),
        (1.0, 0.0),
        (1.0, math.inf),
    ):
        with pytest.raises(GeometryError) as refused:
            unicycle_trajectories([1.0], [0.0], horizon_s=horizon, step_s=step)
        assert str(refused.value) == (
            f"unicycle_trajectories: horizon_s = {horizon!r}, step_s = {step!r}; expected "
            "horizon_s >= 0 and step_s > 0"
        )
