"""What a campaign runs: its encounters and its plan (SR-RUN-8, SR-FUS-9).

An :class:`Encounter` is a scenario, a seed and a length, and for an airside scenario of
:data:`pipeline.sources.sim.weather_scenarios.WEATHER_SCENARIOS` optionally the weather preset
of :data:`pipeline.sources.sim.weather.WEATHER_PRESETS` it is set in (None: the scenario's own;
a clear-air scenario of :data:`pipeline.sources.sim.scenarios.SCENARIOS` has none).
:func:`encounter_plan` lists a campaign's encounters; :func:`encounter_simulation` builds the
fresh, bounded simulation one of them runs in. Which sensors the robot carries is the
configuration's (``runtime.sim_sensors``), so it is part of the campaign file's configuration
hash, not of an encounter.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

from pipeline.config import SafecaseConfig
from pipeline.sources.sim.scenarios import SCENARIOS, make_simulation
from pipeline.sources.sim.simulation import BOUNDED, Simulation
from pipeline.sources.sim.weather import WEATHER_PRESETS
from pipeline.sources.sim.weather_scenarios import WEATHER_SCENARIOS, weather_simulation

__all__ = [
    "AIRSIDE",
    "NAMED",
    "Encounter",
    "encounter_plan",
    "encounter_simulation",
    "known_scenario",
]

NAMED = tuple(n for n in SCENARIOS if n != "random_encounter")
"""The named clear-air scenarios (every scenario of :data:`SCENARIOS` but the random one)."""

AIRSIDE = tuple(WEATHER_SCENARIOS)
"""The airside scenarios, set in weather (:data:`WEATHER_SCENARIOS`)."""


def known_scenario(name: str) -> bool:
    """Whether ``name`` is a clear-air or an airside scenario."""
    return name in SCENARIOS or name in WEATHER_SCENARIOS


@functools.total_ordering
@dataclass(frozen=True)
class Encounter:
    """One closed-loop run: a scenario, its seed, its length [s], and for an airside scenario
    the weather preset it is set in (``weather``; None: the scenario's own).

    Raises ``ValueError`` when ``weather`` is given for a scenario that is not an airside one
    or names no preset (the weather is part of the key, so it is checked when the encounter is
    made); an unknown scenario is refused when it runs (its row records the error)."""

    scenario: str
    seed: int
    duration_s: float
    weather: str | None = None

    def __post_init__(self) -> None:
        if self.weather is None:
            return
        if self.scenario not in WEATHER_SCENARIOS:
            raise ValueError(
                f"encounter {self.scenario!r}: a weather ({self.weather!r}) is for the airside "
                f"scenarios only ({', '.join(AIRSIDE)}); a clear-air scenario has none"
            )
        if self.weather not in WEATHER_PRESETS:
            raise ValueError(
                f"encounter {self.scenario!r}: unknown weather {self.weather!r}; known: "
                f"{', '.join(WEATHER_PRESETS)}"
            )

    def __lt__(self, other: object) -> bool:
        """Ordered by scenario, seed, length, then weather (its own first)."""
        if not isinstance(other, Encounter):
            return NotImplemented
        return self._order() < other._order()

    def _order(self) -> tuple[str, int, float, str]:
        return (self.scenario, self.seed, self.duration_s, self.weather or "")

    @property
    def label(self) -> str:
        """The scenario as the statistics group it: ``scenario``, or ``scenario@weather`` when
        it is set in a weather other than its own (SR-RUN-8)."""
        return self.scenario if self.weather is None else f"{self.scenario}@{self.weather}"

    @property
    def key(self) -> str:
        """The encounter's name in a campaign file: ``scenario/seed/duration``, with
        ``@weather`` after the scenario when it has one (``reversing_tug_fog@rain/3/12``)."""
        return f"{self.label}/{self.seed}/{self.duration_s:g}"


def encounter_plan(
    encounters: int,
    *,
    named_seeds: int = 0,
    duration_s: float = 15.0,
    first_seed: int = 0,
    scenarios: Sequence[str] = NAMED,
    airside_seeds: int = 0,
    airside_weather: Sequence[str | None] = (None,),
) -> list[Encounter]:
    """``named_seeds`` seeds of every scenario in ``scenarios``, then ``airside_seeds`` seeds of
    every airside scenario (:data:`AIRSIDE`) in each weather of ``airside_weather`` (None: the
    scenario's own), then ``encounters`` random encounters; seeds counted from ``first_seed``,
    every run ``duration_s`` long. Raises ``ValueError`` naming an unknown scenario or
    weather."""
    unknown = [s for s in scenarios if s not in SCENARIOS]
    if unknown:
        raise ValueError(f"unknown scenario(s) {unknown}; known: {', '.join(SCENARIOS)}")
    plan = [
        Encounter(name, first_seed + s, duration_s)
        for name in scenarios
        for s in range(named_seeds)
    ]
    plan += [
        Encounter(name, first_seed + s, duration_s, weather)
        for name in AIRSIDE
        for weather in airside_weather
        for s in range(airside_seeds)
    ]
    plan += [Encounter("random_encounter", first_seed + s, duration_s) for s in range(encounters)]
    return plan


def encounter_simulation(config: SafecaseConfig, encounter: Encounter) -> Simulation:
    """A fresh simulation of ``encounter``, keeping a bounded result (a campaign keeps rows):
    :func:`make_simulation` for a clear-air scenario, :func:`weather_simulation` in the
    encounter's weather for an airside one. Raises ``ValueError`` for an unknown scenario."""
    if encounter.scenario in WEATHER_SCENARIOS:
        return weather_simulation(
            config,
            encounter.scenario,
            encounter.seed,
            encounter.duration_s,
            encounter.weather,
            retention=BOUNDED,
        )
    if encounter.scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario {encounter.scenario!r}")
    return make_simulation(
        config, encounter.scenario, encounter.seed, encounter.duration_s, retention=BOUNDED
    )
