"""The braking watch measures deceleration under a STOP only when it means something (A-1)."""

from __future__ import annotations

import math

import pytest

from pipeline.config import default_config
from safety.model.braking import BrakingWatch
from safety.model.monitors import Observation, braking

CODE = ["safety/model/braking.py", "safety/model/monitors.py"]


def _positions(decel_mps2: float, v0_mps: float, stamps: list[float]) -> list[float]:
    """Arc length at each stamp braking from ``v0`` at t = 0 (at rest once stopped)."""
    out = []
    for t in stamps:
        stop_t = v0_mps / decel_mps2
        t = min(t, stop_t)
        out.append(v0_mps * t - 0.5 * decel_mps2 * t * t)
    return out


@pytest.mark.requirement("SR-RUN-6", kind="example", code=CODE)
def test_a_constant_deceleration_is_measured_once_the_stop_has_reached_the_actuator() -> None:
    watch = BrakingWatch(control_cycle_s=0.1, decel_max_mps2=2.5)
    stamps = [0.05 + 0.1 * k for k in range(12)]
    arc = _positions(0.5, 1.0, stamps)
    got = [
        watch.observe(t, (s, 0.0, 0.0), stop_since_s=0.0) for t, s in zip(stamps, arc, strict=True)
    ]
    # The first span (from 0.05 s) starts before the STOP reached the actuator (0.1 s).
    assert got[:3] == [None, None, None]
    measured = [g for g in got if g is not None]
    assert measured
    assert measured == pytest.approx([0.5] * len(measured))
    # No STOP in force: nothing is measured.
    idle = BrakingWatch(0.1, 2.5)
    assert all(
        idle.observe(t, (s, 0.0, 0.0), None) is None for t, s in zip(stamps, arc, strict=True)
    )


@pytest.mark.requirement("SR-RUN-6", kind="example", code=CODE)
def test_a_robot_at_rest_or_a_clock_that_runs_back_is_not_read_as_weak_braking() -> None:
    watch = BrakingWatch(control_cycle_s=0.1, decel_max_mps2=2.5)
    stamps = [0.2 + 0.1 * k for k in range(8)]
    arc = _positions(2.0, 1.0, [t - 0.2 for t in stamps])  # at rest after 0.5 s
    got = [
        watch.observe(t, (s, 0.0, 0.0), stop_since_s=0.0) for t, s in zip(stamps, arc, strict=True)
    ]
    assert all(g is None or g >= 1.9 for g in got), got
    assert watch.observe(0.1, (0.0, 0.0, 0.0), 0.0) is None  # stamps ran back: start afresh
    assert watch.observe(math.nan, (0.0, 0.0, 0.0), 0.0) is None


@pytest.mark.requirement("SR-RUN-6", kind="example", code=CODE)
def test_the_braking_monitor_stops_naming_the_assumption_below_the_tolerance() -> None:
    cfg = default_config().monitors
    weak = braking(Observation(1.0, braking_decel_mps2=0.9, braking_min_mps2=1.25), cfg)
    assert weak.action.value == "STOP"
    assert "braking assumption (A-1) does not hold" in weak.reason
    assert (
        braking(Observation(1.0, braking_decel_mps2=1.0, braking_min_mps2=1.25), cfg).reason == ""
    )
    assert braking(Observation(1.0), cfg).reason == ""
    nan = braking(Observation(1.0, braking_decel_mps2=math.nan, braking_min_mps2=1.25), cfg)
    assert nan.action.value == "STOP"
