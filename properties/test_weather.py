"""Weather in the simulator: fog and rain degrade the LiDAR as modelled (SR-SIM-6).

The attenuated range is cross-checked against scipy's Lambert W (``R = W(alpha R0) / alpha``
solves ``R^2 exp(2 alpha R) = R0^2``); scans of random scenes in random weather are checked beam
by beam against their ground truth (no return beyond the attenuated range, every spurious echo
within the backscatter band and nearer than the surface, the observed loss and echo rates
within a 5-sigma binomial band of the model's probabilities); clear weather makes no extra
random draw, so a run without weather draws exactly a weatherless scanner's stream.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import lambertw

from evidence.profiles import examples
from evidence.record import current
from pipeline.config import default_config
from pipeline.sources.sim.lidar import Lidar, LidarSpec, ScannerPoses, attenuated_range_m
from pipeline.sources.sim.scenarios import ScenarioError, lidar_spec_from_config, make_simulation
from pipeline.sources.sim.weather import (
    BACKSCATTER_MAX_RANGE_M,
    CLEAR,
    WEATHER_PRESETS,
    Weather,
    weather_lidar,
)
from pipeline.sources.sim.weather_scenarios import weather_simulation
from pipeline.types import FloatArray
from properties.sim_strategies import RandomScene, random_scenes

CODE = ["pipeline/sources/sim/weather.py", "pipeline/sources/sim/lidar.py"]
SCENARIOS_CODE = "pipeline/sources/sim/weather_scenarios.py"


def _fixed(pose: tuple[float, float, float]) -> ScannerPoses:
    def poses(t: FloatArray) -> FloatArray:
        return np.tile(np.array(pose), (np.atleast_1d(t).shape[0], 1))

    return poses


@pytest.mark.requirement("SR-SIM-6", kind="cross-check", code=CODE)
@settings(max_examples=examples(200))
@given(r0=st.floats(0.5, 300.0), alpha=st.floats(1e-6, 2.0))
def test_attenuated_range_equals_lambert_w(r0: float, alpha: float) -> None:
    ours = attenuated_range_m(r0, alpha)
    reference = float(np.real(lambertw(alpha * r0))) / alpha
    assert math.isclose(ours, reference, rel_tol=1e-10), (ours, reference)
    assert 0.0 < ours < r0


@pytest.mark.requirement("SR-SIM-6", kind="property", code=CODE)
@settings(max_examples=examples(100))
@given(v1=st.floats(5.0, 5000.0), factor=st.floats(1.01, 10.0), rain=st.floats(0.0, 50.0))
def test_denser_fog_shortens_the_range(v1: float, factor: float, rain: float) -> None:
    spec = LidarSpec.generic(360, max_range_m=30.0)
    thick = weather_lidar(spec, Weather("a", visibility_m=v1, rain_mmph=rain))
    thin = weather_lidar(spec, Weather("b", visibility_m=v1 * factor, rain_mmph=rain))
    assert thick.attenuated_max_range_m < thin.attenuated_max_range_m < spec.max_range_m
    assert thick.backscatter_prob > thin.backscatter_prob


def _binomial_ok(hits: int, trials: int, p: float) -> bool:
    """``hits`` of ``trials`` within 5 standard deviations of ``p`` (plus one count)."""
    sd = math.sqrt(trials * p * (1.0 - p))
    return abs(hits - trials * p) <= 5.0 * sd + 1.0


@pytest.mark.requirement("SR-SIM-6", kind="property", code=CODE)
@settings(max_examples=examples(40), deadline=None)
@given(
    scene=random_scenes(),
    visibility=st.one_of(st.just(math.inf), st.floats(15.0, 400.0)),
    rain=st.floats(0.0, 40.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_weather_degrades_each_beam_as_modelled(
    scene: RandomScene, visibility: float, rain: float, seed: int
) -> None:
    weather = Weather("drawn", visibility_m=visibility, rain_mmph=rain)
    base = LidarSpec.generic(720, max_range_m=25.0, range_noise_std_m=0.01, dropout_prob=0.01)
    spec = weather_lidar(base, weather)
    lidar = Lidar(spec, np.random.default_rng(seed))
    r_cut = spec.attenuated_max_range_m
    n_scans = 6
    echo_trials = echo_hits = lost_trials = lost_hits = 0
    for k in range(n_scans):
        scan, truth = lidar.scan(scene.world, _fixed(scene.pose), 0.1 * k)
        r = scan.ranges_m
        spurious, lost = truth.spurious, truth.weather_lost
        if not weather.active:
            assert not spurious.any()
            assert not lost.any()
        # Every return: a spurious echo in the backscatter band, or within the attenuated range.
        finite = np.isfinite(r)
        assert np.all(r[spurious] >= spec.min_range_m)
        assert np.all(r[spurious] <= BACKSCATTER_MAX_RANGE_M)
        assert np.all(r[finite & ~spurious] <= r_cut + 1e-12)
        # An echo is never farther than what the beam would have returned without it.
        would = truth.true_range_m + spec.noise_bound_m
        assert np.all(~spurious | ~(r > would))
        # Rates: losses among the returns the weather could lose (within the attenuated range),
        # echoes among every beam whose own return was no nearer than the drawn echo.
        before = ~truth.dropout & np.isfinite(truth.true_range_m)
        within = before & (truth.true_range_m + spec.noise_bound_m < r_cut)
        within &= truth.true_range_m - spec.noise_bound_m > BACKSCATTER_MAX_RANGE_M
        lost_trials += int(np.count_nonzero(within))
        lost_hits += int(np.count_nonzero(within & lost))
        far = truth.true_range_m - spec.noise_bound_m > BACKSCATTER_MAX_RANGE_M
        echo_trials += int(np.count_nonzero(far))
        echo_hits += int(np.count_nonzero(far & spurious))
    assert _binomial_ok(lost_hits, lost_trials, spec.weather_dropout_prob), (
        lost_hits,
        lost_trials,
        spec.weather_dropout_prob,
    )
    assert _binomial_ok(echo_hits, echo_trials, spec.backscatter_prob), (
        echo_hits,
        echo_trials,
        spec.backscatter_prob,
    )
    rec = current()
    rec.count("weather", "fog" if math.isfinite(visibility) else "no fog")
    rec.count("beams", "spurious echo", echo_hits)
    rec.count("beams", "lost to rain", lost_hits)


@pytest.mark.requirement("SR-SIM-6", kind="property", code=CODE)
def test_clear_weather_draws_nothing_more() -> None:
    config = default_config()
    spec = lidar_spec_from_config(config)
    for name, weather in WEATHER_PRESETS.items():
        degraded = weather_lidar(spec, weather)
        assert (degraded is spec) == (not weather.active), name
    assert weather_lidar(spec, CLEAR) is spec
    assert not spec.weather_active
    # A scanner without weather makes exactly its five fixed draws per beam and scan (noise,
    # mixed pixel, side, blend, dropout), the stream of a scanner without weather.
    sim = make_simulation(config, "reversing_forklift_aisle", 4, 0.5)
    witness = np.random.default_rng(np.random.SeedSequence(4).spawn(3)[1])
    for _ in range(sim.n_scans):
        sim.next_frame()
        witness.standard_normal(spec.n_beams)
        for _ in range(4):
            witness.random(spec.n_beams)
    assert sim.lidar._rng.random() == witness.random()


@pytest.mark.requirement("SR-SIM-6", kind="property", code=[*CODE, SCENARIOS_CODE])
def test_weather_runs_reproduce_bit_for_bit() -> None:
    config = default_config()
    spec = weather_lidar(lidar_spec_from_config(config), WEATHER_PRESETS["night_fog"])
    scans = []
    for _ in range(2):
        sim = weather_simulation(config, "night_fog_walker_behind_tug", 9, 1.0)
        assert sim.lidar.spec == spec
        scans.append([f.scan.ranges_m.tobytes() for f in iter(sim.next_frame, None)])
    assert scans[0] == scans[1]
    other = weather_simulation(config, "night_fog_walker_behind_tug", 10, 1.0)
    assert [f.scan.ranges_m.tobytes() for f in iter(other.next_frame, None)] != scans[0]
    with pytest.raises(ScenarioError, match="unknown weather scenario"):
        weather_simulation(config, "no_such_scenario", 1, 1.0)
    with pytest.raises(ScenarioError, match="unknown weather 'monsoon'"):
        weather_simulation(config, "night_fog_walker_behind_tug", 1, 1.0, "monsoon")
    clear = weather_simulation(config, "night_fog_walker_behind_tug", 9, 1.0, "clear")
    assert clear.lidar.spec == lidar_spec_from_config(config)


@pytest.mark.requirement("SR-SIM-6", kind="property", code=[*CODE, SCENARIOS_CODE])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_fog_hides_the_far_agent_from_the_lidar(seed: int, evidence: Any) -> None:
    """In the night-fog scenario the agent 28-32 m ahead is beyond the attenuated range (about
    10.6 m) in every scan, while the clear-air scanner (30 m) would reach it on the way."""
    config = default_config()
    sim = weather_simulation(config, "night_fog_walker_behind_tug", seed, 8.0)
    reach = sim.lidar.spec.attenuated_max_range_m
    assert reach < 11.0
    far = [o.object_id for o in sim.world.objects].index(3)
    echoes = 0
    frames = list(iter(sim.next_frame, None))
    for frame in frames:
        t = frame.truth
        # Nearest point of the agent (a 0.5 m figure) is farther than the LiDAR reaches, and
        # no return lies beyond that reach: the agent returns nothing.
        gap = math.hypot(t.x_m[far] - t.scanner_pose[0], t.y_m[far] - t.scanner_pose[1]) - 0.5
        assert gap > reach
        r = frame.scan.ranges_m
        assert np.all(r[np.isfinite(r)] <= reach + 1e-9)
        echoes += int(np.count_nonzero(r <= BACKSCATTER_MAX_RANGE_M))
    evidence.table(
        f"night_fog_walker_behind_tug, seed {seed}, 8 s",
        ["scans", "LiDAR reach [m]", "returns <= 2.5 m (backscatter band)"],
        [[len(frames), round(reach, 2), echoes]],
    )


@pytest.mark.requirement("SR-SIM-6", kind="property", code=CODE)
def test_presets_degrade_in_order(evidence: Any) -> None:
    """The named conditions, as the configured scanner sees them: thicker fog reaches less."""
    spec = lidar_spec_from_config(default_config())
    rows: list[list[object]] = []
    reach: dict[str, float] = {}
    for name, weather in WEATHER_PRESETS.items():
        s = weather_lidar(spec, weather)
        reach[name] = s.attenuated_max_range_m
        rows.append([
            name, round(s.attenuated_max_range_m, 2), round(s.backscatter_prob, 4),
            round(s.weather_dropout_prob, 3), round(weather.lwir_extinction_per_m, 4),
            weather.lens_contamination,
        ])  # fmt: skip
    evidence.table(
        f"weather presets and the configured scanner ({spec.max_range_m:g} m in clear air)",
        ["preset", "LiDAR reach [m]", "backscatter / beam", "rain loss / beam",
         "LWIR extinction [1/m]", "lens contamination"],
        rows,
    )  # fmt: skip
    assert (
        reach["night_fog"] < reach["fog"] < reach["heavy_rain"] < reach["rain"] < spec.max_range_m
    )
    assert reach["clear"] == reach["night"] == reach["day_sun"] == spec.max_range_m
