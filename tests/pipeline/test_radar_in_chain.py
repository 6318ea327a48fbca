"""Radar in the perception chain with a moving robot (SR-FUS-9): the chain runs the radar's
front-end with the frame's pose and twist, and a moving robot without a twist STOPs."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.fusion import doppler_row, fuse, thermal_in_frame
from pipeline.perception import Perceived, Perception
from pipeline.sensors.radar import RadarCounts, RadarFrontEnd, RadarGate, degradation_index
from pipeline.sensors.radar_counts import RadarFusionCounts
from pipeline.sources.sim.sensors_source import sensors_beside
from pipeline.sources.sim.weather import WEATHER_PRESETS
from pipeline.sources.sim.weather_scenarios import weather_simulation
from pipeline.track.tracker import Tracker
from pipeline.types import NOISE_LABEL, Action, Frame, FusionCounts
from safety.model.freshness import is_fresh
from safety.run import cycle_input
from safety.runtime import Runtime

CODE = ["pipeline/perception.py", "pipeline/sensors/radar.py", "safety/cycle.py"]
CONFIG = overridden(default_config(), {"runtime": {"sim_sensors": ["radar"]}})


def _frames(n: int) -> list[Frame]:
    """``n`` frames of the reversing tug in clear air, the robot driving at 1 m/s (open loop),
    with the simulated radar and the robot's twist."""
    sim = weather_simulation(CONFIG, "reversing_tug_fog", 1, 0.1 * n + 0.05, "clear")
    source = sensors_beside(CONFIG, sim, ["radar"], weather=WEATHER_PRESETS["clear"])
    return list(source.frames())[:n]


def _with_radar(frames: list[Frame]) -> list[Frame]:
    """The frames from the radar's first scan on (after its phase, in the second frame)."""
    assert frames[1].radar is not None
    return frames[1:] if frames[0].radar is None else frames


@pytest.fixture(scope="module")
def perceived() -> list[tuple[Frame, Perceived]]:
    chain = Perception.from_config(CONFIG, guard=is_fresh)
    return [(frame, chain.perceive(frame)) for frame in _with_radar(_frames(25))]


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_a_moving_robots_radar_updates_its_track_with_the_compensated_doppler(
    perceived: list[tuple[Frame, Perceived]],
) -> None:
    front, gate = RadarFrontEnd(CONFIG), RadarGate.from_config(CONFIG)
    checked = 0
    for frame, p in perceived:
        assert frame.twist is not None
        assert frame.radar is not None
        assert frame.pose is not None
        if p.fused.counts.n_radar_matched == 0 or frame.twist.vx_mps < 0.5:
            continue
        # The chain's fusion is the front-end's own numbers fused with the radar gate.
        kept, _ = front.filter(frame.radar, frame.pose, None)
        section = CONFIG.radar
        index = degradation_index(
            p.points.range_m,
            p.clusters.point_labels == NOISE_LABEL,
            section.degraded_within_m,
            section.degraded_noise_fraction,
        )
        framed = front.in_tracking_frame(frame.radar, kept, frame.pose, frame.twist, index)
        # The cycle's fusion counts carry the front-end's account and the degradation index.
        counts = p.fused.counts
        assert isinstance(counts, RadarFusionCounts)
        assert counts.n_radar_returns == frame.radar.n
        front_counts = front.filter(frame.radar, frame.pose, None)[1]
        assert counts.n_radar_clutter == front_counts.n_clutter
        assert counts.n_radar_low_rcs == front_counts.n_low_rcs
        assert counts.n_radar == front_counts.n_kept
        assert counts.radar_degradation == index
        thermal = None if frame.thermal is None else thermal_in_frame(frame.thermal, frame.pose)
        want = fuse(
            frame.received_s, p.tracked.tracks, CONFIG.fusion, guard=is_fresh,
            confidence=p.classification.confidence, thermal=thermal, radar=framed,
            radar_gate=gate,
        )  # fmt: skip
        np.testing.assert_array_equal(p.fused.tracks.state, want.tracks.state)
        np.testing.assert_array_equal(p.fused.radar_index, want.radar_index)
        # The tug's compensated Doppler is its own speed along the ray (the raw one is off by
        # the robot's 1 m/s), and the update moved the track's velocity towards it.
        for track in np.flatnonzero(p.fused.radar_index >= 0):
            r = int(p.fused.radar_index[track])
            h = doppler_row(framed.bearing_rad[r : r + 1])[0, 2:]
            state = p.tracked.tracks.state[track]
            rate = float(framed.radial_velocity_mps[r])
            before = abs(float(h @ state[2:]) - rate)
            after = abs(float(h @ p.fused.tracks.state[track, 2:]) - rate)
            assert after < before or before < 1e-9
            raw = float(frame.radar.radial_velocity_mps[np.flatnonzero(kept)[r]])
            assert abs(raw - rate) > 0.5, (raw, rate)
            checked += 1
    assert checked >= 5, checked


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_the_compensated_doppler_is_the_tugs_own_radial_speed() -> None:
    sim = weather_simulation(CONFIG, "reversing_tug_fog", 2, 2.05, "clear")
    source = sensors_beside(CONFIG, sim, ["radar"], weather=WEATHER_PRESETS["clear"])
    front = RadarFrontEnd(CONFIG)
    seen = 0
    for frame in source.frames():
        report = source.last
        assert report is not None
        if report.radar_capture is None:  # before the radar's first scan
            continue
        assert report.radar_truth is not None
        assert frame.radar is not None
        assert frame.pose is not None
        assert frame.twist is not None
        kept, _ = front.filter(frame.radar, frame.pose, None)
        framed = front.in_tracking_frame(frame.radar, kept, frame.pose, frame.twist, 0.0)
        own = np.flatnonzero(report.radar_truth[kept] == 1)
        # The tug's velocity when the radar scanned it.
        state = sim.world.objects[0].trajectory.at(np.array([report.radar_capture.stamp_s]))
        v = np.array([state["vx_mps"][0], state["vy_mps"][0]])
        for r in own:
            b = float(framed.bearing_rad[r])
            truth = math.cos(b) * v[0] + math.sin(b) * v[1]
            assert abs(float(framed.radial_velocity_mps[r]) - truth) < 5 * 0.1 + 0.05
            seen += 1
    assert seen >= 15, seen


@pytest.mark.requirement("SR-FUS-9", kind="example", code=CODE)
def test_a_moving_robot_without_a_twist_stops_with_the_reason() -> None:
    frames = _with_radar(_frames(7))
    runtime = Runtime(CONFIG)
    for i, frame in enumerate(frames):
        blind = i == 4
        out = runtime.step(
            cycle_input(replace(frame, twist=None) if blind else frame, CONFIG, 0.05)
        )
        reasons = [r for r in out.command.reasons if r.startswith("stage:")]
        if blind:
            assert out.command.action is Action.STOP
            assert reasons
            assert reasons[0].startswith("stage:fusion: PerceptionError: radar:")
            assert "twist" in reasons[0]
        else:
            assert not reasons, reasons


@pytest.mark.requirement("SR-FUS-9", kind="example", code=["pipeline/sensors/radar_counts.py"])
def test_the_radar_account_must_add_up() -> None:
    kept = FusionCounts(n_radar=2, n_radar_matched=1, n_radar_unmatched=1)
    front = RadarCounts(n_returns=5, n_low_rcs=1, n_clutter=2, n_kept=2)
    counts = RadarFusionCounts.of(kept, front, 0.4, 0.4)
    assert (counts.n_radar_returns, counts.n_radar_clutter, counts.n_radar_matched) == (5, 2, 1)
    with pytest.raises(ValueError, match="must sum to 6"):
        RadarFusionCounts(n_radar=2, n_radar_matched=2, n_radar_returns=6, n_radar_low_rcs=3)


@pytest.mark.requirement("SR-FUS-9", kind="example", code=[*CODE, "pipeline/track/tracker.py"])
@pytest.mark.parametrize("write_back", [True, False])
def test_the_radar_refined_state_persists_in_the_tracker(write_back: bool) -> None:
    """With ``radar.write_back`` every radar-matched track's fused state is the tracker's own
    state after the cycle (and so the next prediction's start); without it the tracker keeps
    the LiDAR-only state."""
    config = overridden(CONFIG, {"radar": {"write_back": write_back}})
    chain = Perception.from_config(config, guard=is_fresh)
    written = 0
    for frame in _with_radar(_frames(25)):
        p = chain.perceive(frame)
        counts = p.fused.counts
        assert isinstance(counts, RadarFusionCounts)
        assert isinstance(chain.tracker, Tracker)
        kept = chain.tracker.snapshot()
        row = {int(i): k for k, i in enumerate(kept.track_id)}
        matched = np.flatnonzero(p.fused.radar_index >= 0)
        assert counts.n_radar_written_back == (matched.shape[0] if write_back else 0)
        for m in matched:
            k = row[int(p.fused.tracks.track_id[m])]
            source = p.fused.tracks if write_back else p.tracked.tracks
            np.testing.assert_array_equal(kept.state[k], source.state[m])
            np.testing.assert_array_equal(kept.covariance[k], source.covariance[m])
            written += 1
    assert written >= 5, written
