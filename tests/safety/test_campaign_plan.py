"""A campaign's encounters, their order, names and simulations (SR-RUN-8), each read whole."""

from __future__ import annotations

import pytest

from pipeline.config import SafecaseConfig
from pipeline.sources.sim.simulation import BOUNDED
from safety.campaign_plan import (
    AIRSIDE,
    NAMED,
    Encounter,
    encounter_plan,
    encounter_simulation,
    known_scenario,
)

CODE = ["safety/campaign_plan.py"]


def test_the_named_and_airside_scenarios_are_listed_apart() -> None:
    assert NAMED == (
        "reversing_forklift_aisle",
        "crossing_pedestrian",
        "pallet_jack_slow",
        "occlusion_behind_cart",
        "forklift_pass_by",
        "dolly_train_turn",
        "tug_overtaking",
    )
    assert AIRSIDE == ("night_fog_walker_behind_tug", "reversing_tug_fog")
    assert [known_scenario(n) for n in ("random_encounter", *NAMED, *AIRSIDE)] == [True] * 10
    assert not known_scenario("fog")
    assert not known_scenario("")


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_encounters_sort_by_scenario_seed_length_then_weather_own_first() -> None:
    shuffled = [
        Encounter("reversing_tug_fog", 1, 12.0, "rain"),
        Encounter("b", 2, 5.0),
        Encounter("reversing_tug_fog", 1, 12.0),
        Encounter("b", 1, 6.0),
        Encounter("reversing_tug_fog", 1, 12.0, "clear"),
        Encounter("a", 9, 5.0),
        Encounter("b", 1, 5.0),
    ]
    assert [e.key for e in sorted(shuffled)] == [
        "a/9/5",
        "b/1/5",
        "b/1/6",
        "b/2/5",
        "reversing_tug_fog/1/12",
        "reversing_tug_fog@clear/1/12",
        "reversing_tug_fog@rain/1/12",
    ]
    first = Encounter("a", 1, 5.0)
    assert not first < Encounter("a", 1, 5.0)
    assert first <= Encounter("a", 1, 5.0)
    assert first.__lt__("a/1/5") is NotImplemented
    with pytest.raises(TypeError):
        _ = first < ("a", 1, 5.0)


def test_a_key_gives_the_length_as_written() -> None:
    assert Encounter("random_encounter", 4, 12.5).key == "random_encounter/4/12.5"
    assert Encounter("random_encounter", 4, 0.25).key == "random_encounter/4/0.25"


def test_the_refusals_name_the_scenario_the_weather_and_what_is_allowed() -> None:
    with pytest.raises(ValueError) as clear_air:
        Encounter("crossing_pedestrian", 0, 5.0, "fog")
    assert str(clear_air.value) == (
        "encounter 'crossing_pedestrian': a weather ('fog') is for the airside scenarios only "
        "(night_fog_walker_behind_tug, reversing_tug_fog); a clear-air scenario has none"
    )
    with pytest.raises(ValueError) as preset:
        Encounter("reversing_tug_fog", 0, 5.0, "mist")
    assert str(preset.value) == (
        "encounter 'reversing_tug_fog': unknown weather 'mist'; known: clear, day_sun, night, "
        "fog, night_fog, rain, heavy_rain"
    )
    with pytest.raises(ValueError) as scenario:
        encounter_plan(1, scenarios=("crossing_pedestrian", "fog", "mist"))
    assert str(scenario.value) == (
        "unknown scenario(s) ['fog', 'mist']; known: reversing_forklift_aisle, "
        "crossing_pedestrian, pallet_jack_slow, occlusion_behind_cart, forklift_pass_by, "
        "dolly_train_turn, tug_overtaking, random_encounter"
    )
    with pytest.raises(ValueError) as airside:
        encounter_plan(1, scenarios=("reversing_tug_fog",))
    assert "unknown scenario(s) ['reversing_tug_fog']" in str(airside.value)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_the_plan_runs_named_then_airside_then_random_from_the_first_seed() -> None:
    plan = encounter_plan(
        2,
        named_seeds=2,
        duration_s=7.0,
        first_seed=30,
        scenarios=("tug_overtaking", "crossing_pedestrian"),
        airside_seeds=2,
        airside_weather=(None, "night"),
    )
    assert [e.key for e in plan] == [
        "tug_overtaking/30/7",
        "tug_overtaking/31/7",
        "crossing_pedestrian/30/7",
        "crossing_pedestrian/31/7",
        "night_fog_walker_behind_tug/30/7",
        "night_fog_walker_behind_tug/31/7",
        "night_fog_walker_behind_tug@night/30/7",
        "night_fog_walker_behind_tug@night/31/7",
        "reversing_tug_fog/30/7",
        "reversing_tug_fog/31/7",
        "reversing_tug_fog@night/30/7",
        "reversing_tug_fog@night/31/7",
        "random_encounter/30/7",
        "random_encounter/31/7",
    ]
    assert {e.duration_s for e in plan} == {7.0}
    assert [e.key for e in encounter_plan(3)] == [f"random_encounter/{s}/15" for s in range(3)]
    assert encounter_plan(0) == []


def test_each_encounter_gets_a_fresh_bounded_simulation_of_its_own_kind(
    safecase_config: SafecaseConfig,
) -> None:
    for encounter, weather in (
        (Encounter("crossing_pedestrian", 3, 2.0), None),
        (Encounter("reversing_tug_fog", 4, 2.5), "fog"),
        (Encounter("reversing_tug_fog", 5, 2.0, "rain"), "rain"),
    ):
        sim = encounter_simulation(safecase_config, encounter)
        assert (sim.name, sim.seed, sim.duration_s, sim.weather) == (
            encounter.scenario,
            encounter.seed,
            encounter.duration_s,
            weather,
        )
        assert sim._retention is BOUNDED
    one = Encounter("crossing_pedestrian", 3, 2.0)
    assert encounter_simulation(safecase_config, one) is not encounter_simulation(
        safecase_config, one
    )
    with pytest.raises(ValueError) as unknown:
        encounter_simulation(safecase_config, Encounter("nowhere", 0, 1.0))
    assert str(unknown.value) == "unknown scenario 'nowhere'"
