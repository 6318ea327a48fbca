"""Campaigns over the airside scenarios, in a weather, with the simulated sensors (SR-RUN-8,
SR-FUS-9): the plan and the keys (old keys unchanged), rows that read back (old rows too), the
tables per ``scenario@weather``, the command's options, and real closed-loop encounters with the
thermal camera and the radar, the shadow oracle and the oracle's own run beside them."""

from __future__ import annotations

import gzip
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from evidence.cli.main import app
from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.jsoncodec import dumps
from pipeline.sources.sim import rig
from pipeline.sources.sim.sensors_source import SensorsSource, sensors_beside
from properties.campaign_rows import campaign_row
from properties.cli_runner import run_safecase
from safety.campaign import CampaignLog, CampaignRow, pending, run_encounter
from safety.campaign_plan import AIRSIDE, NAMED, Encounter, encounter_plan, encounter_simulation
from safety.campaign_stats import availability_table, bound_table

CODE = ["safety/campaign_plan.py", "safety/campaign.py"]
SENSORS = overridden(default_config(), {"runtime": {"sim_sensors": ["thermal", "radar"]}})
C10K = Path(__file__).parents[2] / "docs/findings/data/c10k-e938d19.jsonl.gz"


def _row(encounter: Encounter, *, nuisance: int = 4, moving: tuple[float, ...] = ()) -> CampaignRow:
    causes = {"zone:UNKNOWN": nuisance}
    return campaign_row(
        encounter, moving, nuisance=nuisance, causes=causes, share=0.5, route_m=40.0
    )


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_the_plan_runs_every_airside_scenario_in_each_weather() -> None:
    plan = encounter_plan(
        2, named_seeds=1, duration_s=12.0, first_seed=7, airside_seeds=2,
        airside_weather=(None, "rain"),
    )  # fmt: skip
    named = [e for e in plan if e.scenario in NAMED]
    airside = [e for e in plan if e.scenario in AIRSIDE]
    randoms = [e for e in plan if e.scenario == "random_encounter"]
    assert len(named) == len(NAMED)
    assert len(randoms) == 2
    assert set(AIRSIDE) == {"night_fog_walker_behind_tug", "reversing_tug_fog"}
    assert sorted((e.scenario, e.weather or "", e.seed) for e in airside) == sorted(
        (name, weather, seed) for name in AIRSIDE for weather in ("", "rain") for seed in (7, 8)
    )
    assert len({e.key for e in plan}) == len(plan)  # the weather keeps the keys apart
    # Without airside seeds the plan is what it was, and so are its keys.
    plain = encounter_plan(1, named_seeds=1, duration_s=12.0, first_seed=7)
    assert [e.key for e in plain] == [f"{n}/7/12" for n in NAMED] + ["random_encounter/7/12"]
    own = Encounter("reversing_tug_fog", 3, 12.0)
    rain = Encounter("reversing_tug_fog", 3, 12.0, "rain")
    assert (own.key, rain.key) == ("reversing_tug_fog/3/12", "reversing_tug_fog@rain/3/12")
    assert (own.label, rain.label) == ("reversing_tug_fog", "reversing_tug_fog@rain")
    assert sorted([rain, own]) == [own, rain]  # its own weather first, no None-to-str compare


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_a_weather_is_refused_where_it_means_nothing() -> None:
    with pytest.raises(ValueError, match=r"'crossing_pedestrian'.*airside scenarios only"):
        Encounter("crossing_pedestrian", 0, 5.0, "fog")
    with pytest.raises(ValueError, match=r"unknown weather 'mist'; known: clear"):
        Encounter("reversing_tug_fog", 0, 5.0, "mist")
    with pytest.raises(ValueError, match="airside scenarios only"):
        Encounter("random_encounter", 0, 5.0, "clear")
    with pytest.raises(ValueError, match=r"unknown weather 'mist'"):
        encounter_plan(0, airside_seeds=1, airside_weather=(None, "mist"))


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_an_airside_row_reads_back_and_an_old_row_reads_as_it_was(tmp_path: Path) -> None:
    row = _row(Encounter("night_fog_walker_behind_tug", 2, 12.0, "night"))
    line = json.loads(dumps(row.to_json()))
    assert line["weather"] == "night"
    assert CampaignRow.from_json(line) == row
    own = _row(Encounter("night_fog_walker_behind_tug", 2, 12.0))
    assert CampaignRow.from_json(json.loads(dumps(own.to_json()))) == own
    # A row of the 10,000-encounter campaign, written before encounters had a weather.
    with gzip.open(C10K, "rt", encoding="utf-8") as handle:
        handle.readline()  # the header
        old: dict[str, Any] = json.loads(handle.readline())
    assert "weather" not in old
    read = CampaignRow.from_json(old)
    assert read.encounter.weather is None
    assert read.encounter.key == f"random_encounter/{old['seed']}/12"
    assert {k: v for k, v in read.to_json().items() if k != "weather"} == old
    # Such a line resumes: its encounter is done, the same seed in a weather is not.
    path = tmp_path / "c.jsonl"
    with CampaignLog.open(path, SafecaseConfig()):
        pass
    with path.open("a", encoding="utf-8") as handle:
        handle.write(dumps(old) + "\n")
        handle.write(dumps(row.to_json()) + "\n")
    plan = [read.encounter, row.encounter, own.encounter]
    with CampaignLog.open(path, SafecaseConfig()) as log:
        assert log.rows == [read, row]
        assert pending(plan, log) == [own.encounter]


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign_stats.py"])
def test_the_tables_keep_each_weather_on_its_own_line() -> None:
    fog = Encounter("reversing_tug_fog", 0, 12.0)
    clear = Encounter("reversing_tug_fog", 0, 12.0, "clear")
    rows = [
        _row(fog, nuisance=10, moving=(0.4,)),
        replace(_row(clear, nuisance=0), closest_m=0.75),
        _row(fog, nuisance=6),
    ]
    bounds = bound_table(rows)
    assert [line[:5] for line in bounds] == [
        ["reversing_tug_fog", "2", "1", "0", "1.50"],
        ["reversing_tug_fog@clear", "1", "0", "0", "0.75"],
        ["all", "3", "1", "0", "0.75"],
    ]
    assert bound_table([replace(rows[1], closest_m=float("inf"))])[0][4] == "-"
    figures = availability_table(rows)
    assert [line[:4] for line in figures] == [
        ["reversing_tug_fog", "2", "20.0 %", "16.0 %"],
        ["reversing_tug_fog@clear", "1", "20.0 %", "0.0 %"],
        ["all", "3", "20.0 %", "10.7 %"],
    ]


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["evidence/cli/campaign.py"])
def test_the_command_refuses_bad_weather_and_sensors(tmp_path: Path) -> None:
    """Exit 2 naming the bad name and what is allowed, before any file or cluster (each call
    plans no random encounter, so a command that let a bad name through runs little)."""
    out = tmp_path / "c.jsonl"
    for option, value, allowed in (
        ("--weather", "own,mist", "own, clear, day_sun"),
        ("--sensors", "thermal,lidar", "thermal, radar, none"),
    ):
        result = CliRunner().invoke(
            app,
            [
                "campaign",
                "--encounters",
                "0",
                "--airside-seeds",
                "1",
                option,
                value,
                "--duration",
                "0.5",
                "--out",
                str(out),
            ],
        )
        assert result.exit_code == 2, result.output
        bad = value.split(",")[1]
        assert f"{option}: '{bad}' is not one of {allowed}" in " ".join(result.output.split())
    result = CliRunner().invoke(
        app, ["campaign", "--encounters", "0", "--sensors", "none,radar", "--out", str(out)]
    )
    assert result.exit_code == 2
    assert "'none' stands alone" in result.output
    assert not out.exists()


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["evidence/cli/campaign.py"])
@pytest.mark.requirement("SR-FUS-9", kind="example", code=["evidence/cli/campaign.py"])
def test_the_sensors_option_is_part_of_the_file_configuration(tmp_path: Path) -> None:
    """``--sensors`` sets ``runtime.sim_sensors``: a file written with the sensors resumes (here
    finished: reported per scenario@weather, no cluster) with the same option and is refused
    without it or with other sensors."""
    path = tmp_path / "c.jsonl"
    plan = encounter_plan(0, duration_s=4.0, airside_seeds=1, airside_weather=("clear",))
    with CampaignLog.open(path, SENSORS) as log:
        for encounter in plan:
            log.add(_row(encounter))
    args = ["campaign", "--encounters", "0", "--airside-seeds", "1", "--weather", "clear",
            "--duration", "4", "--out", str(path)]  # fmt: skip
    done = run_safecase(*args, "--sensors", "radar,thermal,radar")
    assert done.returncode == 0, done.stderr
    assert "2 of 2 runs done" in done.stdout
    assert "closest [m]" in done.stdout
    assert "reversing_tug_fog@clear" in done.stdout
    assert "night_fog_walker_behind_tug@clear" in done.stdout
    for other in ([], ["--sensors", "radar"], ["--sensors", "none"]):
        refused = CliRunner().invoke(app, [*args, *other])
        assert refused.exit_code == 2, (other, refused.output)
        assert "written with configuration" in refused.output


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
@pytest.mark.requirement("SR-FUS-9", kind="example", code=[*CODE, "safety/availability.py"])
def test_an_airside_encounter_runs_with_both_sensors_the_shadow_and_the_oracle(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``reversing_tug_fog`` for 5 s with the thermal camera and the radar in the loop, which see
    the encounter's weather: in clear air the robot drives (no contact while moving) and the
    shadow oracle finds no nuisance STOP; in the scenario's own fog the backscatter holds it at
    rest, every STOP a nuisance one and its progress a small share of the oracle's, which reads
    the simulation's truth and drives on."""
    sources: list[SensorsSource] = []

    def spy(*args: Any, **kwargs: Any) -> SensorsSource:
        sources.append(sensors_beside(*args, **kwargs))
        return sources[-1]

    monkeypatch.setattr(rig, "sensors_beside", spy)
    clear = Encounter("reversing_tug_fog", 0, 5.0, "clear")
    assert encounter_simulation(SENSORS, clear).weather == "clear"
    row = run_encounter(SENSORS, clear, oracle=True)
    assert row.error is None
    assert row.cycles == 50
    assert row.moving_contacts_mps == ()
    assert row.progress_m > 4.0
    assert row.closest_m > 1.0
    assert row.nuisance_cycles == 0
    assert row.progress_share is not None
    assert row.progress_share > 0.9
    assert len(sources) == 2  # ours and the oracle's closed loop, each with both sensors
    for source in sources:
        assert source.camera is not None
        assert source.radar is not None
        assert source.camera[0].weather.name == "clear"
        assert source.last is not None  # it ran to the end
    fog = run_encounter(SENSORS, Encounter("reversing_tug_fog", 0, 5.0), oracle=True)
    assert sources[-1].camera is not None
    assert sources[-1].camera[0].weather.name == "fog"
    assert fog.moving_contacts_mps == ()
    assert fog.progress_m < 0.5
    assert fog.commands == {"STOP": 50}
    assert fog.nuisance_cycles == 50
    assert fog.progress_share is not None
    assert fog.progress_share < 0.2
