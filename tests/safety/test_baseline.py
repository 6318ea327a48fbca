"""The Nav2-style baseline, zone by zone and at each zone's edge (SR-AVL-4).

properties/test_availability.py checks the baseline against GEOS and the tutorial's zones on
a wall; here each zone model is met at its boundary (``min_points`` points and one fewer, a
point on the circle, the approach step that first collides), with the reasons it gives, and a
cycle is stepped through for each command it can give.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.types import Action, FloatArray, Scan
from safety.baseline import Nav2Baseline, points_inside
from safety.cycle import CycleInput
from safety.nav2 import Nav2ParamsError
from safety.nav2.params import parse_params

CODE = ["safety/baseline.py"]
SPEED = 1.0


@pytest.fixture(scope="module")
def config() -> SafecaseConfig:
    return overridden(default_config(), {"stopping": {"robot_max_speed_mps": SPEED}})


def _baseline(config: SafecaseConfig, zones: str, names: str) -> Nav2Baseline:
    text = (
        "collision_monitor:\n  ros__parameters:\n"
        f'    observation_sources: ["scan"]\n    polygons: [{names}]\n' + zones
    )
    return Nav2Baseline(config, parse_params(text))


def _circle(name: str, action: str, radius: float, extra: str = "") -> str:
    return (
        f'    {name}:\n      type: "circle"\n      action_type: "{action}"\n'
        f"      radius: {radius}\n      min_points: 3\n" + extra
    )


def _at(x: float, y: float = 0.0, n: int = 1) -> tuple[FloatArray, FloatArray]:
    return np.full(n, x), np.full(n, y)


@pytest.mark.requirement("SR-AVL-4", kind="example", code=CODE)
def test_a_zone_acts_from_min_points_points_on_its_edge(config: SafecaseConfig) -> None:
    base = _baseline(config, _circle("Stop", "stop", 1.0), '"Stop"')
    assert base.speed_mps(*_at(1.0, n=3)) == (0.0, ("nav2:Stop: stop -> 0.000 m/s",))
    assert base.speed_mps(*_at(1.0, n=2)) == (SPEED, ())
    assert base.speed_mps(*_at(1.0001, n=3)) == (SPEED, ())
    # Three points on the circle in three directions.
    x, y = np.array([0.6, 0.0, -0.8]), np.array([0.8, -1.0, 0.6])
    assert base.speed_mps(x, y)[0] == 0.0


@pytest.mark.requirement("SR-AVL-4", kind="example", code=CODE)
def test_the_strictest_triggered_zone_sets_the_speed_and_each_says_so(
    config: SafecaseConfig,
) -> None:
    zones = (
        _circle("Look", "none", 3.0)
        + _circle("Slow", "slowdown", 2.0, "      slowdown_ratio: 0.6\n")
        + _circle("Cap", "limit", 1.5, "      linear_limit: 0.4\n")
        + _circle("Loose", "limit", 1.5, "      linear_limit: 2.0\n")
        + _circle("Off", "stop", 3.0, "      enabled: false\n")
    )
    base = _baseline(config, zones, '"Look", "Slow", "Cap", "Loose", "Off"')
    assert base.speed_mps(*_at(2.5, n=3)) == (SPEED, ())
    assert base.speed_mps(*_at(1.8, n=3)) == (0.6, ("nav2:Slow: slowdown -> 0.600 m/s",))
    assert base.speed_mps(*_at(1.0, n=3)) == (
        0.4,
        ("nav2:Slow: slowdown -> 0.600 m/s", "nav2:Cap: limit -> 0.400 m/s"),
    )
    # A limit above the command caps nothing: the command passes.
    loose = _baseline(
        config, _circle("Loose", "limit", 1.5, "      linear_limit: 2.0\n"), '"Loose"'
    )
    assert loose.speed_mps(*_at(1.0, n=3)) == (SPEED, ())


@pytest.mark.requirement("SR-AVL-4", kind="example", code=CODE)
def test_the_approach_model_counts_a_collision_at_the_start_of_its_step(
    config: SafecaseConfig,
) -> None:
    """The footprint (here the zone's 0.4 m box from -0.2 to 0.2) moves 0.1 m per 0.1 s step
    at 1 m/s for at most 1 s: a point 0.45 m ahead is inside after the third step (0.3 m
    moved), so the command is scaled by that step's start, 0.2 s of 1 s."""
    approach = (
        '    Ahead:\n      type: "polygon"\n      action_type: "approach"\n'
        '      points: "[[0.2, 0.2], [0.2, -0.2], [-0.2, -0.2], [-0.2, 0.2]]"\n'
        "      min_points: 1\n      time_before_collision: 1.0\n"
        "      simulation_time_step: 0.1\n"
    )
    base = _baseline(config, approach, '"Ahead"')
    speed, reasons = base.speed_mps(*_at(0.45))
    assert speed == pytest.approx(0.2)
    assert reasons == ("nav2:Ahead: approach -> 0.200 m/s",)
    assert base.speed_mps(*_at(0.15)) == (0.0, ("nav2:Ahead: approach -> 0.000 m/s",))
    assert base.speed_mps(*_at(0.25))[0] == 0.0  # inside after the first step: its start is 0
    # The last step reaches 1.2 m: a point there is still within the time; beyond it is not.
    assert base.speed_mps(*_at(1.15))[0] == pytest.approx(0.9)
    assert base.speed_mps(*_at(1.25)) == (SPEED, ())
    # Inside where it stands, though a step forward leaves the point behind: already a collision.
    assert base.speed_mps(*_at(-0.15))[0] == 0.0
    # A step that does not divide the time: the last step starts at 0.9 s, inside the 1 s, and
    # reaches 1.2 m.
    coarse = _baseline(config, approach.replace("step: 0.1", "step: 0.3"), '"Ahead"')
    assert coarse.speed_mps(*_at(1.35))[0] == pytest.approx(0.9)
    assert coarse.speed_mps(*_at(1.45)) == (SPEED, ())
    # 0.3 s in steps of 0.1 s is three steps, though 0.3 / 0.1 is 2.9999999999999996 in doubles.
    short = _baseline(config, approach.replace("collision: 1.0", "collision: 0.3"), '"Ahead"')
    assert short.speed_mps(*_at(0.45))[0] == pytest.approx(0.2 / 0.3)


@pytest.mark.requirement("SR-AVL-4", kind="example", code=CODE)
def test_an_approach_zone_without_points_uses_the_configured_footprint(
    config: SafecaseConfig,
) -> None:
    approach = (
        '    Ahead:\n      type: "polygon"\n      action_type: "approach"\n'
        '      footprint_topic: "footprint"\n      min_points: 1\n'
        "      time_before_collision: 1.0\n      simulation_time_step: 0.1\n"
    )
    base = _baseline(config, approach, '"Ahead"')
    front = 0.5 * config.geometry.footprint_length_m
    side = 0.5 * config.geometry.footprint_width_m
    assert base.speed_mps(*_at(front - 0.01))[0] == 0.0
    assert base.speed_mps(*_at(front + 0.25))[0] == pytest.approx(0.2)
    # The footprint's every corner: just inside each side stops, just outside does not.
    for x, y in ((front, side), (front, -side), (-front, -side), (-front, side)):
        inside = (x * 0.98, y * 0.98)
        outside = (x * 0.98, y * 1.02)
        assert base.speed_mps(*_at(*inside))[0] == 0.0, inside
        assert base.speed_mps(np.array([outside[0]]), np.array([outside[1]]))[0] > 0.0, outside


@pytest.mark.requirement("SR-AVL-4", kind="example", code=CODE)
def test_zones_the_baseline_cannot_model_are_refused_naming_them(config: SafecaseConfig) -> None:
    velocity = (
        '    V:\n      type: "velocity_polygon"\n      action_type: "stop"\n'
        '      velocity_polygons: ["all"]\n      all:\n'
        '        points: "[[1, 0.4], [1, -0.4], [0, -0.4], [0, 0.4]]"\n'
        "        linear_min: 0.0\n        linear_max: 1.0\n"
        "        theta_min: -1.0\n        theta_max: 1.0\n"
    )
    with pytest.raises(Nav2ParamsError) as caught:
        _baseline(config, velocity, '"V"')
    assert str(caught.value) == "V: velocity polygons are not supported by the baseline"
    moving = (
        '    M:\n      type: "polygon"\n      action_type: "stop"\n'
        '      polygon_sub_topic: "stop_zone"\n'
    )
    with pytest.raises(Nav2ParamsError) as caught:
        _baseline(config, moving, '"M"')
    assert str(caught.value) == (
        "M: a shape set at run time (stop_zone) is not supported by the baseline; give its points"
    )


def test_points_inside_follows_the_even_odd_rule() -> None:
    """A square with a notch: a point in the notch is outside, one beside it inside."""
    notched = np.array([[0, 0], [4, 0], [4, 4], [3, 4], [3, 1], [1, 1], [1, 4], [0, 4]], float)
    x = np.array([2.0, 0.5, 3.5, 2.0, 5.0, -0.5])
    y = np.array([3.0, 3.0, 3.0, 0.5, 2.0, 2.0])
    assert points_inside(notched, x, y).tolist() == [False, True, True, True, False, False]
    # No edge spans the points' height: nothing is inside.
    assert not points_inside(notched, np.array([2.0]), np.array([9.0])).any()


def test_points_inside_counts_the_boundary_as_nav2_does() -> None:
    """collision_monitor counts an edge when the point's y is in (lower end, upper end] and the
    crossing lies strictly beyond the point: on the square [0, 2]^2 the top and left edges are
    inside, the bottom and right edges outside (the top-left corner inside, the other corners
    outside); a ray through a side vertex counts once."""
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    x = np.array([1.0, 1.0, 0.0, 2.0, 0.0, 2.0, 0.0, 2.0])
    y = np.array([0.0, 2.0, 1.0, 1.0, 0.0, 0.0, 2.0, 2.0])
    on_edges = points_inside(square, x, y).tolist()
    assert on_edges == [False, True, True, False, False, False, True, False]
    # The same square wound the other way round gives the same answer.
    assert points_inside(square[::-1].copy(), x, y).tolist() == on_edges
    # Rays through the diamond's side vertices, from outside, inside and beyond; its bottom and
    # top vertices are outside (each edge meets the ray at the point itself, not beyond it).
    diamond = np.array([[1, 0], [2, 1], [1, 2], [0, 1]], float)
    x = np.array([-1.0, 1.0, 3.0, 1.0, 1.0])
    y = np.array([1.0, 1.0, 1.0, 0.0, 2.0])
    assert points_inside(diamond, x, y).tolist() == [False, True, False, False, False]


def _scan(stamp_s: float, range_m: float) -> Scan:
    angles = np.linspace(-0.5, 0.5, 41)
    return Scan(stamp_s, angles, np.full(angles.shape, range_m))


@pytest.mark.requirement("SR-AVL-4", kind="example", code=CODE)
def test_a_cycle_gives_stop_slow_or_proceed_and_records_its_clock(config: SafecaseConfig) -> None:
    zones = _circle("Stop", "stop", 1.0) + _circle(
        "Slow", "slowdown", 3.0, "      slowdown_ratio: 0.5\n"
    )
    base = _baseline(config, zones, '"Stop", "Slow"')
    blind = base.step(CycleInput.standing(None, 10.0, config, charge_s=0.05, delay_s=0.01))
    assert (blind.command.action, blind.command.speed_mps) == (Action.STOP, 0.0)
    assert blind.command.reasons == ("nav2: no scan this cycle",)
    assert blind.command.stamp_s == pytest.approx(10.06)
    assert blind.record.observation.previous_now_s is None
    assert blind.record.observation.scan_stamp_s is None
    assert blind.record.observation.cycle_duration_s == 0.05
    assert blind.decision.governor_command is None
    assert set(blind.wall_s) == {"nav2"}
    outputs = {
        range_m: base.step(
            CycleInput.standing(_scan(10.0 + i, range_m), 10.1 + i, config, charge_s=0.05)
        )
        for i, range_m in enumerate((0.8, 2.0, 5.0))
    }
    actions = {r: (o.command.action, o.command.speed_mps) for r, o in outputs.items()}
    assert actions == {
        0.8: (Action.STOP, 0.0),
        2.0: (Action.SLOW, 0.5),
        5.0: (Action.PROCEED, SPEED),
    }
    assert outputs[2.0].record.observation.previous_now_s == pytest.approx(10.15)
    assert outputs[2.0].record.observation.scan_stamp_s == 11.0
    assert outputs[2.0].record.observation.now_s == outputs[2.0].command.stamp_s
    # What is logged: the command as its decision, no governor inputs, the stage's own time.
    for out in (blind, *outputs.values()):
        assert out.decision.command is out.command
        assert (out.decision.governor_command, out.decision.verdicts) == (None, ())
        assert out.record.decision is out.decision
        assert (out.record.governor_inputs, dict(out.record.inputs)) == (None, {})
        assert dict(out.record.timings_s) == out.wall_s == {"nav2": out.wall_s["nav2"]}
        assert 0.0 <= out.wall_s["nav2"] < 1.0
        assert 0.0 <= out.cpu_s < 1.0
        assert (out.envelopes, out.distances) == (None, None)
    # Without a simulated clock the cycle is charged what it took.
    timed = base.step(CycleInput.standing(None, 20.0, config))
    assert timed.record.observation.cycle_duration_s == timed.wall_s["nav2"]
    assert timed.command.stamp_s == 20.0 + timed.wall_s["nav2"]


@pytest.mark.requirement("SR-AVL-4", kind="example", code=CODE)
def test_a_cycle_is_charged_the_thread_cpu_time_between_its_start_and_its_end(
    config: SafecaseConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The thread's CPU clock read at the start and at the end of the cycle: 250 us apart."""
    base = _baseline(config, _circle("Stop", "stop", 1.0), '"Stop"')
    readings = iter([7_000_000_000, 7_000_250_000])
    monkeypatch.setattr(time, "thread_time_ns", lambda: next(readings))
    out = base.step(CycleInput.standing(_scan(0.0, 5.0), 0.05, config, charge_s=0.05))
    assert out.cpu_s == pytest.approx(250e-6, abs=1e-12)


def test_points_inside_divides_by_a_flat_edge_without_a_warning() -> None:
    """A horizontal edge divides by zero (0/0 on its own height); the crossing test never uses
    that quotient, so no floating-point warning may escape it."""
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        inside = points_inside(square, np.array([1.0, 1.0, 3.0]), np.array([0.0, 1.0, 2.0]))
    assert inside.tolist() == [False, True, False]
