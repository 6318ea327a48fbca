"""The simulated thermal camera and radar on their own clocks (SR-FUS-9, SR-FUS-1, SR-SIM-7,
SR-SIM-8): captures at each sensor's rate and seeded phase, the newest at or before each scan's
stamp used and stamped with its own instant, re-expressed in the robot frame at the scan's
stamp, rendered or scanned once, and fresh at fusion."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.errors import ConfigError
from pipeline.frames import to_child, to_parent
from pipeline.sensors.camera import PinholeCamera
from pipeline.sensors.radar import RadarFrontEnd
from pipeline.sensors.thermal import ThermalDetector
from pipeline.sources.sim.radar import RadarSpec, SimRadar
from pipeline.sources.sim.sensor_timing import SensorClock, radar_at_scan, thermal_at_scan
from pipeline.sources.sim.sensors_source import SensorsReport, SensorsSource, sensors_beside
from pipeline.sources.sim.source import SimSource
from pipeline.sources.sim.thermal_camera import ThermalRenderer
from pipeline.sources.sim.weather import WEATHER_PRESETS
from pipeline.sources.sim.weather_scenarios import weather_simulation
from pipeline.types import Frame, RadarDetections, ThermalDetections
from pipeline.types.sensors import Twist
from safety.run import run
from safety.runtime import Runtime

CODE = ["pipeline/sources/sim/sensors_source.py", "pipeline/sources/sim/sensor_timing.py"]
SENSORS = overridden(default_config(), {"runtime": {"sim_sensors": ["thermal", "radar"]}})
# The robot drives straight ahead at 1 m/s; a baggage tug stands idle 13 m ahead of it (id 1).
SCENE = "night_fog_walker_behind_tug"
TUG = 1


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_the_newest_capture_is_never_one_after_the_stamp() -> None:
    for rate_hz, phase_s in ((30.0, 0.0), (20.0, 0.0123), (7.0, 0.1), (30.0, 1 / 30 - 1e-12)):
        clock = SensorClock(rate_hz, phase_s)
        for k in range(20_000):
            at = clock.instant_s(k)
            assert clock.newest(at) == k
            assert clock.newest(math.nextafter(at, -math.inf)) == (k - 1 if k else None)
            assert clock.newest(0.5 * (at + clock.instant_s(k + 1))) == k
    with pytest.raises(ValueError, match="phase_s"):
        SensorClock(20.0, 0.05)


def _reports(
    config: SafecaseConfig, seed: int, duration_s: float
) -> tuple[SensorsSource, list[tuple[Frame, SensorsReport]]]:
    sim = weather_simulation(config, SCENE, seed, duration_s, "night")
    source = sensors_beside(config, sim, ["thermal", "radar"])
    out = []
    for frame in source.frames():
        assert source.last is not None
        out.append((frame, source.last))
    return source, out


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_each_sensor_captures_at_its_own_rate_and_phase() -> None:
    config = overridden(SENSORS, {"radar": {"rate_hz": 25.0}, "thermal": {"rate_hz": 40.0}})
    phases = set()
    for seed in range(4):
        source, _ = _reports(config, seed, 0.1)
        again, _ = _reports(config, seed, 0.1)
        assert source.camera is not None
        assert source.radar is not None
        clocks = (source.camera[2], source.radar[1])
        assert again.camera is not None
        assert again.radar is not None
        assert (again.camera[2], again.radar[1]) == clocks  # the seed reproduces the phases
        assert [c.rate_hz for c in clocks] == [40.0, 25.0]
        assert all(0.0 <= c.phase_s < 1.0 / c.rate_hz for c in clocks)
        phases.add(clocks)
    assert len(phases) == 4  # and the seeds vary them
    source, reports = _reports(config, 5, 2.0)
    assert source.camera is not None
    assert source.radar is not None
    used = 0
    for frame, report in reports:
        assert frame.scan is not None
        stamp = frame.scan.stamp_s
        for clock, capture, found in (
            (source.camera[2], report.thermal_capture, frame.thermal),
            (source.radar[1], report.radar_capture, frame.radar),
        ):
            if capture is None:  # only before the sensor's first capture
                assert stamp < clock.phase_s
                assert found is None
                continue
            assert capture.stamp_s == clock.instant_s(capture.k)
            # The newest capture at or before the stamp: the next one comes after it.
            assert capture.stamp_s <= stamp < clock.instant_s(capture.k + 1)
            assert 0.0 <= stamp - capture.stamp_s < 1.0 / clock.rate_hz
            # Its detections carry the capture's instant.
            assert found is not None
            assert (found.stamp_s == capture.stamp_s).all()
            used += 1
    assert used >= 2 * (len(reports) - 1), used
    assert any(r.radar is not None and r.radar.n for _, r in reports)


def _synthetic(
    rng: np.random.Generator,
) -> tuple[tuple[float, float, float], Twist, tuple[float, float, float], Twist]:
    """A capture's pose and twist and a scan's, up to 0.1 s and 0.3 m / 0.1 rad apart, the
    robot driving and turning."""
    scan = (*rng.uniform(-20.0, 20.0, 2), float(rng.uniform(-math.pi, math.pi)))
    capture = (scan[0] + rng.uniform(-0.3, 0.3), scan[1] + rng.uniform(-0.3, 0.3),
               scan[2] + rng.uniform(-0.1, 0.1))  # fmt: skip
    twists = [
        Twist(rng.uniform(-2.0, 2.0), rng.uniform(-0.3, 0.3), rng.uniform(-1.0, 1.0))
        for _ in range(2)
    ]
    return (float(scan[0]), float(scan[1]), scan[2]), twists[0], capture, twists[1]


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_a_capture_is_re_expressed_where_the_scan_expects_it() -> None:
    """Detections seen from the capture's pose, put through the re-expression and then the
    chain's own framing at the scan's pose and twist, land on the world's points; the radar's
    compensated Doppler is the target's own velocity along the ray."""
    front = RadarFrontEnd(SENSORS)
    rng = np.random.default_rng(7)
    for _ in range(200):
        scan_pose, scan_twist, capture_pose, capture_twist = _synthetic(rng)
        n = 5
        world = np.stack(
            [scan_pose[0] + rng.uniform(-30, 30, n), scan_pose[1] + rng.uniform(-30, 30, n)], 1
        )
        velocity = rng.uniform(-3.0, 3.0, (n, 2))
        # Thermal: seen in the robot frame at the capture.
        x_c, y_c = to_child(capture_pose, world[:, 0], world[:, 1])
        seen = ThermalDetections(np.full(n, 1.0), x_c, y_c, np.full(n, 0.9))
        moved = thermal_at_scan(seen, capture_pose, scan_pose)
        x_w, y_w = to_parent(scan_pose, moved.x_m, moved.y_m)
        np.testing.assert_allclose(np.stack([x_w, y_w], 1), world, rtol=0.0, atol=1e-9)
        np.testing.assert_array_equal(moved.stamp_s, seen.stamp_s)
        # Radar at (0.45, 0.1) on the robot: range, bearing and the true range rate then.
        mount = (0.45, 0.1)
        m_w = to_parent(capture_pose, np.array([mount[0]]), np.array([mount[1]]))
        w = capture_twist.yaw_rate_rps
        v_body = (capture_twist.vx_mps - w * mount[1], capture_twist.vy_mps + w * mount[0])
        c, s = math.cos(capture_pose[2]), math.sin(capture_pose[2])
        v_radar = np.array([c * v_body[0] - s * v_body[1], s * v_body[0] + c * v_body[1]])
        ray = world - np.array([m_w[0][0], m_w[1][0]])
        rng_m = np.hypot(ray[:, 0], ray[:, 1])
        u = ray / rng_m[:, None]
        rate = np.sum(u * (velocity - v_radar), axis=1)
        bearing = np.arctan2(ray[:, 1], ray[:, 0]) - capture_pose[2]
        raw = RadarDetections(np.full(n, 1.0), rng_m, bearing, rate, *mount)
        moved_r = radar_at_scan(raw, capture_pose, capture_twist, scan_pose, scan_twist)
        framed = front.in_tracking_frame(
            moved_r, np.ones(n, dtype=bool), scan_pose, scan_twist, 0.0
        )
        np.testing.assert_allclose(framed.x_m, world[:, 0], rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(framed.y_m, world[:, 1], rtol=0.0, atol=1e-9)
        own = np.sum(u * velocity, axis=1)
        np.testing.assert_allclose(framed.radial_velocity_mps, own, rtol=0.0, atol=1e-9)
        np.testing.assert_array_equal(framed.stamp_s, raw.stamp_s)


def _exact_radar(phase_s: float) -> SensorsSource:
    """The scene with a noise-free radar (no clutter) at 20 Hz from phase ``phase_s``."""
    sim = weather_simulation(SENSORS, SCENE, 0, 3.0, "night")
    spec = RadarSpec(range_std_m=0.0, azimuth_std_rad=0.0, doppler_std_mps=0.0,
                     clutter_per_scan=0.0)  # fmt: skip
    radar = SimRadar(spec, np.random.default_rng(0))
    return SensorsSource(SimSource(sim), None, (radar, SensorClock(20.0, phase_s)))


def _tug_seen(source: SensorsSource) -> list[tuple[float, float, float, float]]:
    """Per frame: the capture's age [s] and where the standing tug's return lies in the world
    frame, through the chain's own front-end at the frame's pose and twist, and its
    compensated Doppler [m/s]."""
    front = RadarFrontEnd(SENSORS)
    out = []
    for frame in source.frames():
        report = source.last
        if report is None or report.radar_capture is None:
            continue
        assert frame.radar is not None
        assert frame.pose is not None
        assert frame.scan is not None
        assert report.radar_truth is not None
        assert report.twist.vx_mps == pytest.approx(1.0)
        kept, _ = front.filter(frame.radar, frame.pose, None)
        framed = front.in_tracking_frame(frame.radar, kept, frame.pose, frame.twist, 0.0)
        tug = np.flatnonzero(report.radar_truth[kept] == TUG)
        assert tug.shape == (1,)
        age = frame.scan.stamp_s - report.radar_capture.stamp_s
        i = int(tug[0])
        out.append((age, float(framed.x_m[i]), float(framed.y_m[i]),
                    float(framed.radial_velocity_mps[i])))  # fmt: skip
    return out


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_a_standing_tug_stays_put_whatever_the_captures_age() -> None:
    """The robot drives at 1 m/s: a capture at the scan's stamp and one taken 1/rate earlier
    (5 cm of travel before it) put the tug's return on the same world point."""
    at_stamp = _tug_seen(_exact_radar(0.0))
    earlier = _tug_seen(_exact_radar(1e-6))
    # The first frame, at 0 s, is the first capture from phase 0 and before the first from 1e-6.
    assert len(at_stamp) - 1 == len(earlier) >= 25
    for (age_a, xa, ya, da), (age_b, xb, yb, db) in zip(at_stamp[1:], earlier, strict=True):
        assert age_a < 1e-9
        assert age_b == pytest.approx(0.05 - 1e-6, abs=1e-9)
        assert math.hypot(xa - xb, ya - yb) < 1e-6, (xa, xb, ya, yb)
        assert abs(da) < 1e-6  # the tug stands: its own radial speed is 0
        assert abs(db) < 1e-6


def _counted(source: SensorsSource) -> tuple[list[int], list[int]]:
    """Wrap the source's renderer and radar to count their calls per frame."""
    assert source.camera is not None
    assert source.radar is not None
    renderer, radar = source.camera[0], source.radar[0]
    calls = [0, 0]

    def counting(i: int, call: Callable[..., Any]) -> Callable[..., Any]:
        def counted(*args: Any, **kwargs: Any) -> Any:
            calls[i] += 1
            return call(*args, **kwargs)

        return counted

    renderer.render = counting(0, renderer.render)  # type: ignore[method-assign]
    radar.scan = counting(1, radar.scan)  # type: ignore[method-assign]
    renders, scans = [], []
    for _ in source.frames():
        renders.append(calls[0])
        scans.append(calls[1])
        calls[0] = calls[1] = 0
    return renders, scans


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_a_frame_costs_at_most_one_render_and_one_radar_scan() -> None:
    sim = weather_simulation(SENSORS, SCENE, 2, 2.0, "night")
    renders, scans = _counted(sensors_beside(SENSORS, sim, ["thermal", "radar"]))
    # At 30 and 20 Hz every frame after the first uses a new capture of each.
    assert renders[1:] == [1] * (len(renders) - 1)
    assert scans[1:] == [1] * (len(scans) - 1)
    assert renders[0] <= 1
    assert scans[0] <= 1
    # A camera and a radar slower than the LiDAR: a capture that serves two frames is made once.
    sim = weather_simulation(SENSORS, SCENE, 2, 2.0, "night")
    t = SENSORS.thermal
    renderer = ThermalRenderer(sim.world, WEATHER_PRESETS["night"], PinholeCamera.from_config(t),
                               t.netd_c, np.random.default_rng(3))  # fmt: skip
    camera = (renderer, ThermalDetector(t), SensorClock(4.0, 0.01))
    radar = (SimRadar(RadarSpec(), np.random.default_rng(1)), SensorClock(5.0, 0.03))
    renders, scans = _counted(SensorsSource(SimSource(sim), camera, radar))
    assert len(renders) == 20
    assert sum(renders) == 8  # captures 0..7 at 0.01 + k / 4 s serve the frames at 0.1..1.9 s
    assert sum(scans) == 10  # captures 0..9 at 0.03 + k / 5 s
    assert max(renders) == max(scans) == 1


@pytest.mark.requirement("SR-FUS-1", kind="example", code=[*CODE, "pipeline/config/__init__.py"])
def test_the_captures_are_fresh_at_fusion_and_stale_ones_are_skipped() -> None:
    """In the closed loop (each cycle charged ``runtime.sim_cycle_s``) a capture is at most
    1/rate + one revolution + the cycle old at fusion, within the default maximum ages: none is
    stale. With a radar limit below that every radar return is stale: counted and skipped,
    never matched (LiDAR only)."""
    strict = overridden(SENSORS, {"fusion": {"radar_max_age_s": 0.15}})
    for config, stale_radar in ((SENSORS, False), (strict, True)):
        sim = weather_simulation(config, SCENE, 1, 3.0, "night")
        source = sensors_beside(config, sim, ["thermal", "radar"], weather=WEATHER_PRESETS["night"])
        totals: dict[str, float] = {}
        for out in run(config, source, Runtime(config)):
            for key, value in out.record.inputs["fusion"].items():
                totals[key] = totals.get(key, 0) + value
        assert totals["n_thermal"] > 0, totals
        assert totals["n_thermal_stale"] == 0, totals
        assert totals["n_radar"] > 0, totals
        if stale_radar:
            assert totals["n_radar_stale"] == totals["n_radar"], totals
            assert totals["n_radar_matched"] == 0, totals
        else:
            assert totals["n_radar_stale"] == 0, totals
            assert totals["n_radar_matched"] > 0, totals


def test_a_rate_too_slow_for_the_freshness_limit_is_refused() -> None:
    # 1 / rate may not exceed max_age - skew: each capture would go stale before the next.
    with pytest.raises(ConfigError, match=r"radar.rate_hz = 4.0: allowed: at least 5 "):
        overridden(default_config(), {"radar": {"rate_hz": 4.0}})
    with pytest.raises(ConfigError, match=r"thermal.rate_hz = 30.0: allowed: at least 40 "):
        overridden(default_config(), {"fusion": {"thermal_max_age_s": 0.05, "clock_skew_s": 0.025}})
    assert overridden(default_config(), {"radar": {"rate_hz": 5.0}}).radar.rate_hz == 5.0
