"""Scanner layouts, the sensor model and the ego robot (examples)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import ConstantSpeed, Ego, EgoObservation, EgoSpec, Route
from pipeline.sources.sim.lidar import DEVICE_PRESETS, NO_RETURN_ID, STRUCTURE_ID, Lidar, LidarSpec
from pipeline.sources.sim.objects import person
from pipeline.sources.sim.scenarios import lidar_spec_from_config, make_simulation
from pipeline.sources.sim.shapes import rectangle
from pipeline.sources.sim.world import SimObject, Structure, World
from pipeline.types import FloatArray, Scan


def _box_world(with_person: bool = False) -> World:
    walls = Structure.from_parts([("wall", rectangle(4.0, 5.0, -10.0, 10.0))])
    objs: tuple[SimObject, ...] = ()
    if with_person:
        traj = mo.integrate(mo.stationary(), 2.0, 0.0, 0.0, 1.0)
        objs = (SimObject(7, "p", person(), traj, mo.stationary()),)
    return World("box", walls, objs, (-1, 6, -10, 10))


def _at_origin(t: FloatArray) -> FloatArray:
    return np.zeros((np.atleast_1d(t).shape[0], 3))


def test_device_layouts_match_their_datasheets() -> None:
    urg = DEVICE_PRESETS["hokuyo_urg04lx"]()
    assert urg.n_beams == 682
    assert urg.max_range_m == 5.6
    assert math.degrees(urg.angles_rad[0]) == pytest.approx(-119.53, abs=0.01)
    assert math.degrees(urg.angles_rad[-1]) == pytest.approx(119.88, abs=0.01)
    ust = DEVICE_PRESETS["hokuyo_ust10lx"]()
    assert ust.n_beams == 1081
    assert ust.scan_period_s == 0.025
    assert math.degrees(ust.angles_rad[-1]) == pytest.approx(135.0)
    assert DEVICE_PRESETS["rplidar_a2"]().full_circle
    gen = LidarSpec.generic(1080)
    assert gen.full_circle
    assert gen.beam_period_s == pytest.approx(0.1 / 1080)


def test_exact_ranges_and_owners_of_a_wall_and_a_person() -> None:
    spec = LidarSpec.generic(360)
    scan, beams = Lidar(spec, np.random.default_rng(1)).scan(
        _box_world(True), _at_origin, 2.0, seq=3
    )
    assert isinstance(scan, Scan)
    assert scan.seq == 3
    assert scan.beam_period_s == 0.0
    ahead = np.argmin(np.abs(spec.angles_rad))
    assert beams.owner_id[ahead] == STRUCTURE_ID  # straight between the person's legs
    left_leg = np.argmin(np.abs(spec.angles_rad - math.atan2(0.1, 2.0)))
    assert beams.owner_id[left_leg] == 7
    side = np.argmin(np.abs(spec.angles_rad - math.radians(30)))
    assert beams.owner_id[side] == STRUCTURE_ID
    assert scan.ranges_m[side] == pytest.approx(4.0 / math.cos(math.radians(30)))
    behind = np.argmin(np.abs(np.abs(spec.angles_rad) - math.pi))
    assert beams.owner_id[behind] == NO_RETURN_ID
    assert np.isnan(scan.ranges_m[behind])


def test_dropout_rate_and_noise_spread_are_as_configured() -> None:
    spec = LidarSpec.generic(4000, max_range_m=50.0, range_noise_std_m=0.02, dropout_prob=0.1)
    world = World(
        "ring",
        Structure.from_parts(
            [
                ("wall", rectangle(-20, 20, 9.0, 9.5)),
                ("wall", rectangle(-20, 20, -9.5, -9.0)),
                ("wall", rectangle(9.0, 9.5, -9, 9)),
                ("wall", rectangle(-9.5, -9.0, -9, 9)),
            ]
        ),
        (),
        (-10, 10, -10, 10),
    )
    scan, beams = Lidar(spec, np.random.default_rng(5)).scan(world, _at_origin, 0.0)
    assert beams.dropout.mean() == pytest.approx(0.1, abs=0.02)
    err = (scan.ranges_m - beams.true_range_m)[~beams.dropout]
    assert np.std(err) == pytest.approx(0.02, rel=0.1)
    assert np.abs(err).max() <= spec.noise_bound_m + 1e-12


def test_mixed_pixels_appear_at_depth_jumps_only() -> None:
    spec = LidarSpec.generic(720, mixed_pixel_prob=1.0)
    _scan, beams = Lidar(spec, np.random.default_rng(2)).scan(_box_world(True), _at_origin, 0.0)
    assert beams.mixed.sum() >= 2  # both silhouette edges of the person's legs
    with np.errstate(invalid="ignore"):  # inf - inf where both beams see nothing
        jumps = np.abs(np.diff(np.append(beams.true_range_m, beams.true_range_m[0]))) > 0.3
    near_jump = jumps | np.roll(jumps, 1)
    assert np.all(near_jump[beams.mixed])


def test_a_simulation_is_a_scan_source() -> None:
    cfg = overridden(default_config(), {"sim": {"beams": 90}})
    sim = make_simulation(cfg, "crossing_pedestrian", 2, duration_s=1.0)
    scans = list(sim.scans(ConstantSpeed(0.5)))
    assert [s.seq for s in scans] == list(range(10))
    assert all(s.source == "sim:crossing_pedestrian:2" and s.n_beams == 90 for s in scans)
    assert sim.ego.log()["command_mps"][-1] == 0.5


def test_time_skew_spreads_the_beams_over_the_revolution() -> None:
    cfg = overridden(default_config(), {"sim": {"time_skew": True, "beams": 360}})
    spec = lidar_spec_from_config(cfg)
    sim = make_simulation(cfg, "forklift_pass_by", 1, duration_s=1.0, lidar=spec)
    frame = sim.next_frame()
    assert frame is not None
    times = frame.truth.beams.beam_time_s
    assert times[0] == frame.scan.stamp_s == 0.0
    assert np.diff(times) == pytest.approx(np.full(359, 0.1 / 360))
    assert frame.scan.beam_period_s == pytest.approx(0.1 / 360)
    assert frame.observation.stamp_s == pytest.approx(0.1)  # delivered when complete


def _ego(latency: float = 0.1, decel: float = 2.0) -> Ego:
    spec = EgoSpec(
        Route(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])),
        0.9,
        0.6,
        0.5,
        decel,
        latency,
        1.5,
        1.0,
    )
    return Ego(spec, 0.01, 2000)


def test_the_ego_brakes_after_its_latency_at_its_deceleration() -> None:
    ego = _ego(latency=0.1, decel=2.0)
    ego.command(0.0, 0.0)
    for _ in range(100):
        ego.step()
    log = ego.log()
    assert log["speed_mps"][10] == pytest.approx(1.0)  # still at speed during the latency
    assert log["speed_mps"][60] == pytest.approx(0.0)  # 1.0 m/s / 2.0 m/s^2 = 0.5 s later
    # Distance = latency * v + v^2 / (2 b) (plus under one step of discretisation).
    assert ego.arc_m == pytest.approx(0.1 + 0.25, abs=0.011)


def test_the_ego_follows_its_route_round_corners_and_stops_at_the_end() -> None:
    ego = _ego()
    ego.command(1.5, 0.0)
    for _ in range(2000):
        ego.step()
    assert ego.arc_m == pytest.approx(20.0)
    assert ego.speed_mps == 0.0
    assert ego.pose() == pytest.approx([10.0, 10.0, math.pi / 2])


def test_non_finite_or_negative_commands_fail_safe() -> None:
    ego = _ego(latency=0.0)
    ego.command(float("nan"), 0.0)
    ego.step()
    assert ego.target_mps == 0.0
    ego.command(-3.0, 0.01)
    ego.command(99.0, 0.01)
    ego.step()
    assert ego.target_mps == 1.5  # clipped to the robot's maximum


def test_a_governor_plugs_in_as_a_policy_and_can_avoid_the_contact() -> None:
    """A policy is any callable observation -> speed; here a truth-reading stand-in that
    stops when anything is within 2.5 m ahead shows the closed loop working."""

    def cautious(obs: EgoObservation) -> float:
        tr = obs.truth
        dx, dy = tr.x_m - obs.pose[0], tr.y_m - obs.pose[1]
        ahead = (dx > 0) & (np.abs(dy) < 1.5) & (np.hypot(dx, dy) < 5.0)
        return 0.0 if ahead.any() else 1.0

    cfg = overridden(default_config(), {"sim": {"beams": 90}})
    blind = make_simulation(cfg, "reversing_forklift_aisle", 0, 10.0).run(ConstantSpeed(1.0))
    careful = make_simulation(cfg, "reversing_forklift_aisle", 0, 10.0).run(cautious)
    assert blind.contact
    assert not careful.contact
    assert careful.ego_log["speed_mps"][-1] == 0.0
    assert careful.min_separation_m[0] > 0.0
