"""The stopping model by example: hand-computed numbers, the readings, the caps, the finding."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import z3

from pipeline.config import default_config, load_config, overridden
from pipeline.errors import ConfigError
from properties.smt import exact_value
from safety.model.stopping import (
    ClosingClass,
    StoppingParams,
    Tier,
    keymaera_separation_m,
    safe_speed_mps,
    separation_m,
    stopping_time_s,
)

ROOT = Path(__file__).resolve().parents[2]
SOURCE = ROOT / "examples" / "source-warehouse.toml"
F = Fraction


def test_hand_computed_numbers() -> None:
    # T = 0.08 + 0.1 s, A = 0.5 m/s^2, b = 1.25 m/s^2, v = 1 m/s:
    # travel 0.18 + 0.0081 + 1.09^2 / 2.5 = 0.66334 m; stop after 0.18 + 1.09 / 1.25 = 1.052 s.
    T, A, b = F(18, 100), F(1, 2), F(5, 4)
    assert separation_m(F(1), T, A, b, F(0)) == F(66334, 100000)
    assert stopping_time_s(F(1), T, A, b) == F(1052, 1000)
    assert separation_m(F(1), T, A, b, F(6, 10)) == F(66334, 100000) + F(6, 10) * F(1052, 1000)
    assert separation_m(F(0), F(0), F(0), b, F(0)) == 0


def test_float_numpy_fraction_and_z3_readings_agree() -> None:
    args = (0.7, 0.18, 0.5, 1.25, 0.6)
    exact = separation_m(*(F(repr(a)) for a in args))
    assert math.isclose(separation_m(*args), float(exact), rel_tol=1e-15)
    batch = separation_m(*(np.full(3, a) for a in args))
    assert np.all(batch == separation_m(*args))
    v = z3.Real("v")
    symbolic = z3.simplify(z3.substitute(separation_m(v, *args[1:]), (v, z3.RealVal("0.7"))))
    assert F(symbolic.as_fraction()) == exact
    assert keymaera_separation_m(*(F(repr(a)) for a in args)) == exact
    # The safe speed: runtime float vs z3's exact root of separation(v) = 0.9 m.
    speed = safe_speed_mps(0.9, 0.18, 0.5, 1.25, 0.6)
    _, low, high = exact_value(
        v, [v >= 0, separation_m(v, *(F(repr(a)) for a in args[1:])) == F(9, 10)]
    )
    assert low - F(1, 10**15) <= F(speed) <= high + F(1, 10**15)
    assert np.allclose(safe_speed_mps(np.array([0.9, 0.9]), 0.18, 0.5, 1.25, 0.6), speed, rtol=0)


def test_safe_speed_is_zero_when_not_even_standstill_fits() -> None:
    # From standstill, 0.5 m/s^2 for 0.18 s and a person closing at 1.6 m/s need 0.40 m.
    need = separation_m(0.0, 0.18, 0.5, 1.25, 1.6)
    assert safe_speed_mps(need * 0.99, 0.18, 0.5, 1.25, 1.6) == 0.0
    assert safe_speed_mps(need * 1.01, 0.18, 0.5, 1.25, 1.6) > 0.0


@pytest.mark.requirement(
    "SR-STOP-1", kind="example", code=["pipeline/config/", "safety/model/stopping.py"]
)
def test_default_caps_come_from_the_computed_limits() -> None:
    params = StoppingParams.from_config(default_config())
    for tier, configured in zip(Tier, params.caps_mps, strict=True):
        limit = params.tier_limit_mps(tier)
        expected = min(math.floor(limit * 1000) / 1000, params.robot_max_speed_mps)
        assert configured == expected, (tier, limit, configured)
    assert [round(params.tier_limit_mps(t), 6) for t in Tier] == [0.592359, 0.896182, 0.65112]


def test_measured_latency_feeds_in_through_the_seam() -> None:
    config = default_config()
    measured = StoppingParams.from_config(
        config, perception_latency_s=0.063, latency_source="wcet: pWCET 1e-9 of 10,000 cycles"
    )
    assert measured.reaction_s == pytest.approx(0.163)
    assert measured.latency_provenance() == {
        "perception_latency_s": 0.063,
        "control_cycle_s": 0.1,
        "reaction_s": measured.reaction_s,
        "perception_latency_source": "wcet: pWCET 1e-9 of 10,000 cycles",
    }
    assert measured.tier_limit_mps(Tier.HIGH) > StoppingParams.from_config(config).tier_limit_mps(
        Tier.HIGH
    )
    for bad in (-0.01, math.nan, math.inf):
        with pytest.raises(ValueError, match="perception_latency_s"):
            StoppingParams.from_config(config, perception_latency_s=bad)


def test_forklift_closing_speed_is_the_larger_of_stopping_and_prediction() -> None:
    config = overridden(default_config(), {"predict": {"reversal_speed_mps": 0.9}})
    params = StoppingParams.from_config(config)
    assert params.closing_speed_mps(ClosingClass.FORKLIFT_REVERSING) == 0.9
    assert params.tier_closing_mps(Tier.NEAR_REVERSAL) == 0.9
    assert params.worst_closing_speed_mps == 1.6


def test_tiers_by_confidence() -> None:
    params = StoppingParams.from_config(default_config())
    assert params.margin_for(0.95, False) == 0.4
    assert params.margin_for(0.8, False) == 0.4  # the threshold belongs to the higher tier
    assert params.margin_for(0.6, False) == 0.7
    assert params.margin_for(0.2, False) == 1.0  # untrusted class: the most cautious tier
    assert params.margin_for(0.95, True) == 1.0
    assert params.cap_for(0.95, False) == 0.592
    assert list(params.margin_for(np.array([0.9, 0.6, 0.1]), np.array([False, False, False]))) == [
        0.4,
        0.7,
        1.0,
    ]


def test_source_configuration_holds_the_published_figures() -> None:
    config = load_config(SOURCE)
    s = config.stopping
    assert (s.perception_latency_s, s.control_cycle_s) == (0.08, 0.1)
    # braking 0.2-0.4 m at 1.0 m/s
    assert (1.0 / (2 * s.decel_max_mps2), 1.0 / (2 * s.decel_min_mps2)) == (0.2, 0.4)
    assert (s.margin_high_m, s.margin_medium_m, s.margin_near_reversal_m) == (0.4, 0.7, 1.0)
    assert s.robot_max_speed_mps == 1.0
    assert (s.speed_cap_high_mps, s.speed_cap_medium_mps, s.speed_cap_near_reversal_mps) == (
        1.0,
        1.0,
        1.0,
    )
    assert config.predict.reversal_speed_mps == s.forklift_reversing_speed_mps == 0.6


@pytest.mark.requirement("SR-STOP-1", kind="example", code=["safety/model/stopping.py"])
def test_certify_reports_the_source_tiers_refuted_with_safe_caps(tmp_path: Path) -> None:
    env = dict(os.environ, MPLBACKEND="Agg", COLUMNS="400")
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "evidence.cli",
            "certify",
            "--config",
            str(SOURCE),
            "--profile",
            "ci",
            "--no-benchmarks",
            "--out",
            str(tmp_path / "out"),
            "--signing-key",
            str(tmp_path / "key.pem"),
            "-k",
            "test_tier_margin_covers",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
        cwd=ROOT,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    text = done.stdout + done.stderr
    # A slice (-k): only the requirements it touched are judged, and it says so.
    assert "SR-STOP-1" in done.stdout.split("SLICE FAIL")[1]
    assert "test_tier_margin_covers_stopping_up_to_its_cap[high]" in text
    assert "test_tier_margin_covers_stopping_up_to_its_cap[near_reversal]" in text
    assert "tier high (margin 0.4 m, closing 0 m/s) REFUTED at cap 1 m/s" in text
    assert "largest safe cap 0.800000000 m/s (exact 4/5" in text
    assert "tier near_reversal (margin 1 m, closing 0.6 m/s) REFUTED at cap 1 m/s" in text
    assert "largest safe cap 0.881055392 m/s" in text
    assert "tier medium" not in text
    bundle = json.loads(next((tmp_path / "out").glob("*/evidence.json")).read_text())
    assert bundle["summary"]["certification"] == "SLICE FAIL"
    assert bundle["summary"]["judged_requirements"] == ["SR-STOP-1"]
    junit = next((tmp_path / "out").glob("*/junit.xml")).read_text()
    assert '<property name="certification" value="SLICE FAIL"' in junit
    assert '<testcase classname="requirements" name="SR-STOP-1"' in junit
    (stop1,) = [r for r in bundle["requirements"] if r["id"] == "SR-STOP-1"]
    assert stop1["would_be"] == "VIOLATED"
    refuted = [
        d
        for t in bundle["tests"]
        for d in t["details"]
        if d["type"] == "smt" and d["verdict"] == "REFUTED" and d["required"]
    ]
    assert sorted(d["name"] for d in refuted) == [
        "SR-STOP-1 tier high at 1 m/s",
        "SR-STOP-1 tier near_reversal at 1 m/s",
    ]
    assert all(d["model"]["v_mps"]["float"] <= 1.0 for d in refuted)
    assert bundle["provenance"]["stopping.reaction_latency"]["perception_latency_source"] == (
        "source material: 80 ms p99 scan-to-costmap (Intel NUC i5)"
    )


@pytest.mark.requirement("SR-STOP-5", kind="example", code=["pipeline/config/__init__.py"])
def test_the_freshness_monitor_enforces_the_proved_latency() -> None:
    config = default_config()
    assert config.monitors.scan_max_age_s <= config.stopping.perception_latency_s == 0.18
    with pytest.raises(ConfigError) as caught:
        overridden(config, {"monitors": {"scan_max_age_s": 0.25}})
    assert caught.value.lines == [
        "override: monitors.scan_max_age_s (0.25) must not exceed stopping.perception_latency_s "
        "(0.18): the monitor would pass data older than the stopping proof assumes"
    ]
    # The source's 80 ms is valid only with a monitor as strict, and then a 10 Hz scan (first
    # beam 0.1 s old when the revolution completes) is always stale (docs/findings/stopping.md).
    source = load_config(SOURCE)
    assert source.monitors.scan_max_age_s == source.stopping.perception_latency_s == 0.08
