"""The braking assumption watched at run time (A-1; SR-RUN-6).

Property: braking at any deceleration the stopping proof allows is never flagged, whatever the
speed and the scan timing; braking below ``braking_tolerance`` times the least allowed is
flagged whenever it is measured. Campaign: closed-loop runs whose simulated robot brakes within
the assumed range never trip the braking monitor; the same runs with brakes weaker than assumed
do, naming the assumption.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import by_profile, certifying, examples
from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig, overridden
from properties.ahead import ahead
from safety.model.braking import BrakingWatch
from safety.model.monitors import Observation, braking
from safety.run import run_scenario

CODE = ["safety/model/braking.py", "safety/model/monitors.py", "safety/runtime.py"]


def _measured(
    decel: float, v0: float, period: float, jitter: list[float], b_max: float
) -> list[float]:
    watch = BrakingWatch(control_cycle_s=0.1, decel_max_mps2=b_max)
    out = []
    stop_t = v0 / decel
    for k, j in enumerate(jitter):
        t = 0.1 + period * k + j
        s = v0 * min(t, stop_t) - 0.5 * decel * min(t, stop_t) ** 2
        got = watch.observe(t, (s, 0.0, 0.0), stop_since_s=0.0)
        if got is not None:
            out.append(got)
    return out


@pytest.mark.requirement("SR-RUN-6", kind="property", code=CODE)
@settings(max_examples=examples(200), deadline=None)
@given(
    fraction=st.floats(0.0, 1.0),
    v0=st.floats(0.2, 3.0),
    period=st.floats(0.05, 0.2),
    jitter=st.lists(st.floats(-0.004, 0.004), min_size=6, max_size=20),
)
def test_braking_within_the_assumed_range_is_never_flagged_and_weaker_braking_is(
    safecase_config: SafecaseConfig, fraction: float, v0: float, period: float, jitter: list[float]
) -> None:
    s, m = safecase_config.stopping, safecase_config.monitors
    rec = current()
    assumed = s.decel_min_mps2 + fraction * (s.decel_max_mps2 - s.decel_min_mps2)
    for d in _measured(assumed, v0, period, jitter, s.decel_max_mps2):
        verdict = braking(
            Observation(1.0, braking_decel_mps2=d, braking_min_mps2=s.decel_min_mps2), m
        )
        assert verdict.reason == "", (assumed, d)
        rec.count("braking within the range", "measured and not flagged")
    weak = fraction * 0.95 * m.braking_tolerance * s.decel_min_mps2 + 0.01
    for d in _measured(weak, v0, period, jitter, s.decel_max_mps2):
        verdict = braking(
            Observation(1.0, braking_decel_mps2=d, braking_min_mps2=s.decel_min_mps2), m
        )
        assert verdict.action.value == "STOP", (weak, d)
        rec.count("braking below the tolerance", "measured and flagged")


SCENARIOS = ("reversing_forklift_aisle", "crossing_pedestrian", "occlusion_behind_cart")


@pytest.mark.requirement("SR-RUN-6", kind="campaign", code=CODE)
@ahead
def test_the_braking_monitor_trips_on_weak_brakes_and_only_then(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    seeds = range(by_profile(ci=1, certify=2, full=3))
    duration_s = 8.0 if not certifying() else 20.0
    s = safecase_config.stopping
    weak_decel = 0.5 * s.decel_min_mps2
    weak = overridden(
        safecase_config,
        {"sim": {"ego_decel_min_mps2": weak_decel, "ego_decel_max_mps2": weak_decel}},
    )
    rows, totals = [], {"assumed": 0, "weak": 0}
    for name in SCENARIOS:
        for seed in seeds:
            normal = run_scenario(safecase_config, name, seed, duration_s)
            weaker = run_scenario(weak, name, seed, duration_s)
            totals["assumed"] += normal.reasons.get("braking", 0)
            totals["weak"] += weaker.reasons.get("braking", 0)
            rows.append(
                [name, seed, normal.reasons.get("braking", 0), weaker.reasons.get("braking", 0)]
            )
    evidence.table(
        "braking monitor trips per run (cycles with a braking STOP)",
        [
            "scenario",
            "seed",
            f"brakes {s.decel_min_mps2}-{s.decel_max_mps2} m/s^2 (assumed)",
            f"brakes {weak_decel} m/s^2",
        ],
        rows,
        caption="the simulated robot's braking deceleration is drawn per run from "
        "sim.ego_decel_min_mps2 .. sim.ego_decel_max_mps2",
    )
    evidence.counts("braking monitor", totals)
    assert totals["assumed"] == 0
    assert totals["weak"] > 0
