"""The cautious mode of acoustic alerts (SR-ACU-3) and the reversing-beeper scenario in closed
loop (SR-ACU-5).

SR-ACU-3: z3 proofs about :func:`safety.model.caution.cautious_speed_mps` itself, weakened
formulas refuted, and the runtime checked with and without an alert on the same scan. SR-ACU-5:
the ``reversing_beeper`` scenario heard by the simulated array, cautious exactly while fresh.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import z3
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig, default_config
from pipeline.sources.sim.acoustic_scenarios import (
    BEEPER_NAME,
    HearingSimSource,
    reversing_tug_beeping,
)
from pipeline.sources.sim.scenarios import simulation_for_spec
from pipeline.sources.sim.source import SimSource
from pipeline.types import Action, Scan
from pipeline.types.acoustic import AcousticAlert, AlertKind
from properties.smt import Obligation, ProofVerdict, prove, to_z3
from safety.model.caution import CAUTION_MONITOR, cautious_speed_mps
from safety.model.freshness import FRESHNESS_GUARD_S, is_fresh
from safety.model.readings import minimum, select
from safety.run import run
from safety.runtime import CycleInput, Runtime

CAUTION = ["safety/model/caution.py", "safety/runtime.py", "safety/cycle.py"]
SCENARIO = ["pipeline/sources/sim/acoustic_scenarios.py", "safety/runtime.py", "safety/run.py"]


def _caution_vars() -> tuple[tuple[z3.ArithRef, ...], list[z3.BoolRef]]:
    v, now, stamp, age, skew, cap, guard = z3.Reals(
        "speed_mps now_s alert_stamp_s max_age_s skew_s caution_mps guard_s"
    )
    return (v, now, stamp, age, skew, cap, guard), [
        v >= 0,
        age > 0,
        skew >= 0,
        cap >= 0,
        guard >= 0,
    ]


def caution_obligations(formula: Any = cautious_speed_mps) -> list[Obligation]:
    """The cautious mode's claims about ``formula`` (SR-ACU-3), for every real value."""
    (v, now, stamp, age, skew, cap, guard), hyps = _caution_vars()
    out = formula(v, now, stamp, age, skew, cap, guard)
    fresh = is_fresh(now, stamp, age, skew, guard)
    variables = (v, now, stamp, age, skew, cap, guard)
    v_max = z3.Real("max_speed_mps")
    return [
        Obligation(
            "SR-ACU-3 a fresh alert caps the speed",
            "for all v >= 0, stamps, times, max_age > 0, skew >= 0, cap >= 0: fresh implies "
            "cautious(v) <= cap",
            tuple(hyps),
            z3.Implies(fresh, out <= cap),
            variables,
        ),
        Obligation(
            "SR-ACU-3 caution only lowers the speed",
            "for all values: 0 <= cautious(v) <= v",
            tuple(hyps),
            z3.And(out <= v, out >= 0),
            variables,
        ),
        Obligation(
            "SR-ACU-3 a stale alert changes nothing",
            "for all values: not fresh implies cautious(v) = v",
            tuple(hyps),
            z3.Implies(z3.Not(fresh), out == v),
            variables,
        ),
        Obligation(
            "SR-ACU-3 a fresh alert slows no more than the cap demands",
            "for all values: fresh and v >= cap implies cautious(v) = cap (not vacuous)",
            tuple(hyps),
            z3.Implies(z3.And(fresh, v >= cap), out == cap),
            variables,
        ),
        Obligation(
            "SR-ACU-3 the runtime's verdict form is the formula",
            "for all v <= v_max: min(v, cautious(v_max)) = cautious(v) (combine takes the "
            "smallest limit)",
            (*hyps, v <= v_max),
            minimum(v, formula(v_max, now, stamp, age, skew, cap, guard)) == out,
            (*variables, v_max),
        ),
    ]


@pytest.mark.requirement("SR-ACU-3", kind="proof", code=CAUTION)
def test_caution_proofs(safecase_config: SafecaseConfig) -> None:
    for obligation in caution_obligations():
        result = prove(obligation)
        result.attach(required=True)
        assert result.proved, (obligation.name, result.describe_model())
    # The configured instance.
    a = safecase_config.acoustic
    (v, now, stamp, age, skew, cap, guard), hyps = _caution_vars()
    pinned = [
        age == to_z3(a.max_age_s),
        skew == to_z3(a.clock_skew_s),
        cap == to_z3(a.caution_speed_mps),
        guard == to_z3(FRESHNESS_GUARD_S),
    ]
    out = cautious_speed_mps(v, now, stamp, age, skew, cap, guard)
    result = prove(
        Obligation(
            "SR-ACU-3 caution at the configured values",
            f"max age {a.max_age_s} s, skew {a.clock_skew_s} s, cap {a.caution_speed_mps} m/s: "
            "fresh implies cautious(v) <= cap, and cautious(v) <= v",
            (*hyps, *pinned),
            z3.And(z3.Implies(is_fresh(now, stamp, age, skew, guard), out <= cap), out <= v),
        )
    )
    result.attach(required=True)
    assert result.proved, result.describe_model()


@pytest.mark.requirement("SR-ACU-3", kind="proof", code=CAUTION)
def test_a_weakened_caution_is_refuted() -> None:
    def ignores_freshness(
        v: Any, now: Any, stamp: Any, age: Any, skew: Any, cap: Any, guard: Any
    ) -> Any:
        return select(now - stamp <= age, minimum(v, cap), v)  # trusts the stamp, no skew

    def caps_from_above(
        v: Any, now: Any, stamp: Any, age: Any, skew: Any, cap: Any, guard: Any
    ) -> Any:
        return select(is_fresh(now, stamp, age, skew, guard), cap, v)  # may raise the speed

    refuted = {
        name: prove(o).verdict
        for name, o in ((o.name, o) for o in caution_obligations(ignores_freshness))
    }
    assert refuted["SR-ACU-3 a stale alert changes nothing"] is ProofVerdict.REFUTED
    raised = {o.name: prove(o).verdict for o in caution_obligations(caps_from_above)}
    assert raised["SR-ACU-3 caution only lowers the speed"] is ProofVerdict.REFUTED


@pytest.fixture(scope="module")
def runtime_parts() -> tuple[SafecaseConfig, Classifier]:
    config = default_config()
    return config, Classifier.from_config(config.classify)


def _scan_with_wall(distance_m: float, stamp_s: float) -> Scan:
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    ranges = np.full(1080, np.inf)
    ahead = np.abs(angles) < 0.15
    ranges[ahead] = distance_m / np.cos(angles[ahead])
    return Scan(stamp_s, angles, ranges)


@pytest.mark.requirement("SR-ACU-3", kind="property", code=CAUTION)
@settings(max_examples=examples(20))
@given(
    distance_m=st.one_of(st.just(math.inf), st.floats(1.0, 12.0)),
    age_s=st.floats(-0.5, 4.0),
    bearing=st.floats(-3.0, 3.0),
)
def test_the_runtime_is_cautious_only_while_an_alert_is_fresh(
    runtime_parts: tuple[SafecaseConfig, Classifier],
    distance_m: float,
    age_s: float,
    bearing: float,
) -> None:
    config, classifier = runtime_parts
    now = 100.0
    scan = _scan_with_wall(distance_m, now - 0.01)
    alert = AcousticAlert(AlertKind.BEEPER, bearing, 0.8, now - age_s)
    plain = Runtime(config, classifier=classifier).step(
        CycleInput.standing(scan, now, config, charge_s=0.01)
    )
    cautious = Runtime(config, classifier=classifier).step(
        CycleInput.standing(scan, now, config, charge_s=0.01, acoustic=alert)
    )
    # Never a position: the governor reads exactly the same obstacles.
    assert cautious.decision.governor_command == plain.decision.governor_command
    a = config.acoustic
    fresh = bool(is_fresh(now + 0.01, alert.stamp_s, a.max_age_s, a.clock_skew_s))
    rec = current()
    rec.count("alert", "fresh" if fresh else "stale or future")
    if fresh:
        assert cautious.command.speed_mps <= a.caution_speed_mps
        assert cautious.command.speed_mps <= plain.command.speed_mps
        expected = cautious_speed_mps(
            plain.command.speed_mps,
            now + 0.01,
            alert.stamp_s,
            a.max_age_s,
            a.clock_skew_s,
            a.caution_speed_mps,
        )
        if (
            plain.command.action is not Action.STOP
            and expected >= config.governor.min_moving_speed_mps
        ):
            assert cautious.command.speed_mps == expected
        rec.count(
            "caution", "bound" if plain.command.speed_mps > a.caution_speed_mps else "not binding"
        )
    else:
        assert cautious.command == plain.command
    logged = cautious.record.inputs["acoustic"]
    assert logged["caution"] is fresh
    assert [v.monitor for v in cautious.decision.verdicts].count(CAUTION_MONITOR) == 1


@pytest.mark.requirement("SR-ACU-5", kind="example", code=SCENARIO)
def test_the_reversing_beeper_scenario_makes_the_closed_loop_cautious() -> None:
    config = default_config()
    duration = 6.0
    spec = reversing_tug_beeping(np.random.default_rng(5), duration)
    sim = simulation_for_spec(config, spec, "reversing_beeper", 5, duration)
    source = HearingSimSource(SimSource(sim), config.acoustic, np.random.default_rng(6))
    cautious, calm = 0, 0
    a = config.acoustic
    for out in run(config, source, Runtime(config)):
        now = out.record.observation.now_s
        caution = any(r.startswith(CAUTION_MONITOR) for r in out.command.reasons)
        alert = out.detail.inp.acoustic if out.detail is not None else None
        fresh = alert is not None and bool(
            is_fresh(now, alert.stamp_s, a.max_age_s, a.clock_skew_s)
        )
        assert caution is fresh
        if fresh:
            cautious += 1
            assert out.command.speed_mps <= a.caution_speed_mps
        else:
            calm += 1
    # The tug backs up from 1-2 s for 2 s: heard, and the robot is cautious for a while.
    assert source.alerts, "the beeper was never heard"
    assert cautious >= 5, (cautious, calm)
    assert calm >= 5, (cautious, calm)
    assert spec.world.objects[0].name == BEEPER_NAME
    for alert in source.alerts:
        # Never a position: only a bearing, towards the tug (ahead and to the left).
        assert 0.0 < alert.bearing_rad < math.pi / 2, alert


@pytest.mark.requirement("SR-ACU-3", kind="example", code=CAUTION)
def test_an_alert_that_is_not_one_stops_the_robot_with_the_reason(
    runtime_parts: tuple[SafecaseConfig, Classifier],
) -> None:
    config, classifier = runtime_parts
    scan = _scan_with_wall(math.inf, 99.99)
    bad: Any = "beeper"  # what a broken source might hand over
    out = Runtime(config, classifier=classifier).step(
        CycleInput.standing(scan, 100.0, config, charge_s=0.01, acoustic=bad)
    )
    assert out.command.action is Action.STOP
    assert any(r.startswith(CAUTION_MONITOR) for r in out.command.reasons)
    assert out.record.inputs["acoustic"] == {"invalid": "str", "caution": True}
