"""A campaign's rows and file without a cluster (SR-RUN-8).

:func:`safety.campaign.run_campaign` is run here with no client, so every encounter runs in
this process (:func:`pipeline.distributed.as_done`): the bookkeeping of a campaign (what runs,
what is logged, what a failure leaves) is checked without a Dask cluster, which
``properties/test_campaign.py`` starts for the distribution itself.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig, config_hash
from pipeline.jsoncodec import dumps
from properties.campaign_rows import campaign_row
from safety.availability import our_runtime
from safety.campaign import (
    CampaignError,
    CampaignLog,
    CampaignRow,
    Encounter,
    cpu_summary_ms,
    failed_row,
    run_campaign,
    run_encounter,
)
from safety.campaign_plan import encounter_simulation
from safety.run import run_simulation

SHORT = Encounter("crossing_pedestrian", 0, 1.5)
"""A short run that still moves at its end (its last two arc lengths differ)."""


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_failed_row_counts_nothing_but_its_error() -> None:
    encounter = Encounter("tug_overtaking", 4, 2.0)
    assert failed_row(encounter, "ValueError: x") == CampaignRow(
        encounter=encounter,
        cycles=0,
        commands={},
        contacts=0,
        moving_contacts_mps=(),
        closest_m=float("inf"),
        progress_m=0.0,
        route_m=0.0,
        cpu_ms={},
        error="ValueError: x",
        nuisance_cycles=None,
        nuisance_causes={},
        progress_share=None,
    )


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_the_cpu_summary_is_in_milliseconds() -> None:
    # 101 cycles of 1 ms .. 101 ms: the percentiles fall on samples, no interpolation
    summary = cpu_summary_ms([i * 1e-3 for i in range(101, 0, -1)])
    assert summary == {
        "p50": pytest.approx(51.0),
        "p99": pytest.approx(100.0),
        "max": pytest.approx(101.0),
    }
    assert list(summary) == ["p50", "p99", "max"]
    assert cpu_summary_ms([]) == {}


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_file_that_cannot_resume_is_named_with_the_reason(tmp_path: Path) -> None:
    config = SafecaseConfig()
    empty = tmp_path / "empty.jsonl"
    empty.write_text('{"format": "safecase-campaign/1"')  # no newline: not even a header
    with pytest.raises(CampaignError) as caught:
        CampaignLog.open(empty, config)
    assert str(caught.value) == f"{empty}: not a campaign file (no header line)"
    other = SafecaseConfig.model_validate({"campaign": {"max_contact_rate": 0.02}})
    theirs, ours = config_hash(other), config_hash(config)
    path = tmp_path / "c.jsonl"
    with CampaignLog.open(path, other):
        pass
    with pytest.raises(CampaignError) as caught:
        CampaignLog.open(path, config)
    assert str(caught.value) == (
        f"{path}: written with configuration {theirs[:16]}, this configuration hashes to "
        f"{ours[:16]}; start a new file"
    )


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_new_file_is_made_with_its_folders_and_holds_its_rows(tmp_path: Path) -> None:
    path = tmp_path / "a" / "b" / "c.jsonl"
    row = campaign_row(Encounter("reversing_tug_fog", 2, 5.0, "rain"))
    with CampaignLog.open(path, SafecaseConfig()) as log:
        assert log.path == path
        log.add(row)
        assert log.rows == [row]
    assert json.loads(path.read_text().splitlines()[1])["weather"] == "rain"
    with CampaignLog.open(path, SafecaseConfig()) as log:
        assert log.rows == [row]
        assert log.rows[0].encounter.weather == "rain"


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_row_without_a_weather_key_is_in_its_own_weather() -> None:
    data = campaign_row(Encounter("reversing_tug_fog", 2, 5.0)).to_json()
    del data["weather"]
    assert CampaignRow.from_json(json.loads(dumps(data))).encounter.weather is None


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_an_encounter_refused_says_why(safecase_config: SafecaseConfig) -> None:
    with pytest.raises(ValueError, match=r"^unknown scenario 'no_such_scenario'$"):
        run_encounter(safecase_config, Encounter("no_such_scenario", 0, 1.0))
    with pytest.raises(ValueError, match=r"^oracle=True needs the shadow oracle \(shadow=True\)$"):
        run_encounter(safecase_config, SHORT, oracle=True, shadow=False)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_row_is_the_run_it_summarises(safecase_config: SafecaseConfig) -> None:
    """The row's figures are those of the same run made directly: same commands, distance
    driven to its last sample, route length, no contact; CPU times in milliseconds."""
    row = run_encounter(safecase_config, SHORT, shadow=False)
    sim = encounter_simulation(safecase_config, SHORT)
    model = Classifier.from_config(safecase_config.classify)
    alone = run_simulation(safecase_config, sim, runtime=our_runtime(safecase_config, sim, model))
    assert alone.sim is not None
    arc = alone.sim.ego_log["arc_m"]
    assert arc[-1] > arc[-2]  # still moving, else the last sample is not told from the one before
    assert row.cycles == alone.cycles
    assert row.commands == dict(alone.actions)
    assert row.progress_m == float(arc[-1])
    assert row.route_m == pytest.approx(alone.sim.ego_spec.route.length_m)
    assert row.route_m > row.progress_m
    assert (row.contacts, row.moving_contacts_mps) == (0, ())
    assert row.closest_m == pytest.approx(float(alone.sim.min_separation_m.min()))
    assert set(row.cpu_ms) == {"p50", "p99", "max"}
    assert 0.0 < row.cpu_ms["p50"] <= row.cpu_ms["p99"] <= row.cpu_ms["max"] < 60_000.0
    assert row.progress_share is None


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_campaign_without_a_cluster_logs_each_row_and_resumes(
    safecase_config: SafecaseConfig, tmp_path: Path
) -> None:
    """Two encounters, one of them refused: both are rows of the file and of the result, the
    refused one as a failed row with its error; each is told to ``on_row`` as it comes. The
    second call runs only what the file lacks, with the oracle, then the third without the
    shadow; the rows come back resumed first."""
    path = tmp_path / "c.jsonl"
    bad = Encounter("no_such_scenario", 0, 1.0)
    told: list[CampaignRow] = []
    with CampaignLog.open(path, safecase_config) as log:
        rows = run_campaign(None, safecase_config, [bad, SHORT], log, told.append)
    assert rows == told
    assert [r.encounter for r in rows] == [bad, SHORT]
    assert rows[0] == failed_row(bad, "ValueError: unknown scenario 'no_such_scenario'")
    assert rows[1].error is None
    assert rows[1].outcome() == run_encounter(safecase_config, SHORT).outcome()
    assert rows[1].nuisance_cycles is not None  # the shadow watches by default
    assert rows[1].progress_share is None  # the oracle does not drive by default
    later = Encounter("crossing_pedestrian", 1, 1.0)
    last = Encounter("crossing_pedestrian", 2, 1.0)
    with CampaignLog.open(path, safecase_config) as log:
        run_campaign(None, safecase_config, [SHORT, later], log, oracle=True)
        rows = run_campaign(None, safecase_config, [later, last], log, shadow=False)
    assert [r.encounter for r in rows] == [bad, SHORT, later, last]
    assert rows[2].progress_share is not None
    assert rows[2].nuisance_cycles is not None
    assert rows[3].nuisance_cycles is None
    with CampaignLog.open(path, safecase_config) as log:
        assert log.rows == rows


class _RefusingClient:
    """A cluster client that refuses every task (stands in for a Dask client)."""

    def submit(self, *args: object, **kwargs: object) -> None:
        raise RuntimeError("submitted to the cluster")


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_campaign_given_a_client_hands_its_encounters_to_it(
    safecase_config: SafecaseConfig, tmp_path: Path
) -> None:
    with CampaignLog.open(tmp_path / "c.jsonl", safecase_config) as log:
        with pytest.raises(RuntimeError, match="submitted to the cluster"):
            run_campaign(_RefusingClient(), safecase_config, [SHORT], log)  # type: ignore[arg-type]
        assert log.rows == []
