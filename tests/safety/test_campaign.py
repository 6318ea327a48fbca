"""The campaign file, the contact-rate bound and the availability figures, without a cluster
(SR-RUN-8).

The bound is checked against an independent reference: the Clopper-Pearson upper limit is by
definition the ``level`` quantile of Beta(k + 1, n - k) (``scipy.stats.beta``), and with no
violation ``1 - (1 - level) ** (1 / n)`` in closed form. A row's nuisance STOPs and progress
share are checked against :func:`safety.availability.compare` on the same seed.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import beta
from typer.testing import CliRunner

from evidence.cli.main import app
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.jsoncodec import dumps
from pipeline.sources.sim.scenarios import make_simulation
from properties.campaign_rows import campaign_row
from safety.availability import compare
from safety.campaign import (
    CampaignError,
    CampaignLog,
    CampaignRow,
    Encounter,
    failed_row,
    run_encounter,
)
from safety.campaign_stats import (
    availability,
    availability_table,
    by_scenario,
    contact_bound,
    cpu_block_maxima,
    nuisance_causes,
    upper_limit,
)
from safety.run import run_simulation
from safety.runtime import Runtime

CODE = ["safety/campaign.py", "safety/campaign_stats.py"]


def _row(
    scenario: str,
    seed: int,
    moving: tuple[float, ...] = (),
    *,
    nuisance: int | None = 4,
    share: float | None = None,
) -> CampaignRow:
    return campaign_row(Encounter(scenario, seed, 5.0), moving, nuisance=nuisance, share=share)


@pytest.mark.requirement("SR-RUN-8", kind="property", code=["safety/campaign_stats.py"])
@given(
    n=st.integers(1, 100_000),
    share=st.floats(0.0, 1.0),
    level=st.sampled_from([0.9, 0.95, 0.99]),
)
def test_the_bound_is_the_beta_quantile(n: int, share: float, level: float) -> None:
    k = round(share * n)
    expected = 1.0 if k == n else float(beta.ppf(level, k + 1, n - k))
    assert upper_limit(k, n, level) == pytest.approx(expected, rel=1e-6, abs=1e-12)
    if k == 0:
        assert upper_limit(0, n, level) == pytest.approx(1 - (1 - level) ** (1 / n), rel=1e-9)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_a_failed_run_counts_as_a_violation() -> None:
    rows = [_row("a", 0), _row("a", 1, (0.4,)), failed_row(Encounter("b", 0, 5.0), "boom")]
    overall = contact_bound(rows)
    assert (overall.runs, overall.violations, overall.errors) == (3, 2, 1)
    per = by_scenario(rows)
    assert list(per) == ["a", "b"]
    assert (per["a"].violations, per["b"].violations) == (1, 1)
    assert contact_bound(rows[:1]).upper_95 == pytest.approx(0.95)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_the_file_resumes_and_refuses_another_configuration(tmp_path: Path) -> None:
    path = tmp_path / "c.jsonl"
    config = SafecaseConfig()
    rows = [_row("random_encounter", 1), failed_row(Encounter("x", 2, 1.0), "E: y")]
    with CampaignLog.open(path, config) as log:
        for row in rows:
            log.add(row)
    with CampaignLog.open(path, config) as log:
        assert log.rows == rows
        assert log.done() == {"random_encounter/1/5", "x/2/1"}
    other = SafecaseConfig.model_validate({"campaign": {"max_contact_rate": 0.02}})
    with pytest.raises(CampaignError, match="configuration"):
        CampaignLog.open(path, other)
    path.write_text(path.read_text() + "not json\n")
    with pytest.raises(CampaignError, match=r"c\.jsonl:4: not a campaign row"):
        CampaignLog.open(path, config)
    (tmp_path / "x.jsonl").write_text('{"hello": 1}\n')
    with pytest.raises(CampaignError, match="not a campaign file"):
        CampaignLog.open(tmp_path / "x.jsonl", config)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_line_cut_short_is_dropped_and_the_rest_kept(tmp_path: Path) -> None:
    path = tmp_path / "c.jsonl"
    config = SafecaseConfig()
    with CampaignLog.open(path, config) as log:
        log.add(_row("random_encounter", 1))
    whole = path.read_bytes()
    path.write_bytes(whole + b'{"scenario": "rand')
    with CampaignLog.open(path, config) as log:
        assert len(log.rows) == 1
        log.add(_row("random_encounter", 2))
    lines = path.read_text().splitlines()
    assert len(lines) == 3
    assert json.loads(lines[2])["seed"] == 2


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_row_counts_the_nuisance_stops_compare_finds(safecase_config: SafecaseConfig) -> None:
    """tug_overtaking seed 3, 2.5 s: the robot stops in 14 of 25 cycles, in 7 of them for the
    tug's cone of reach where the oracle, knowing the tug's true course, would not. The row's
    count, causes and progress share are :func:`compare`'s; the shadow leaves our own run as
    it is alone."""
    name, seed, length = "tug_overtaking", 3, 2.5
    row = run_encounter(safecase_config, Encounter(name, seed, length), oracle=True)
    reference = compare(safecase_config, name, seed, length)
    # some STOPs are nuisance and some are not, else the count checks nothing
    assert 0 < reference.nuisance_cycles < row.commands["STOP"]
    assert row.nuisance_cycles == reference.nuisance_cycles
    assert row.nuisance_causes == dict(reference.nuisance_causes())
    assert row.nuisance_share == pytest.approx(reference.nuisance_share, abs=1 / row.cycles)
    assert row.progress_share == reference.progress_share()
    assert row.progress_share is not None
    assert 0.0 < row.progress_share < 1.0
    alone = run_simulation(
        safecase_config,
        make_simulation(safecase_config, name, seed, length),
        runtime=Runtime(
            safecase_config, classifier=Classifier.from_config(safecase_config.classify)
        ),
    )
    assert alone.sim is not None
    assert row.commands == dict(alone.actions)
    assert row.progress_m == float(alone.sim.ego_log["arc_m"][-1])


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_without_the_shadow_a_row_is_the_same_but_its_nuisance_figures(
    safecase_config: SafecaseConfig,
) -> None:
    """The shadow only watches: leaving it out changes no command, contact or distance of the
    run, only the nuisance figures (None: not counted, so not in the availability figures)."""
    encounter = Encounter("tug_overtaking", 3, 2.5)
    watched = run_encounter(safecase_config, encounter)
    lean = run_encounter(safecase_config, encounter, shadow=False)
    assert watched.nuisance_cycles is not None
    assert watched.nuisance_cycles > 0
    assert lean.nuisance_cycles is None
    assert lean.nuisance_share is None
    assert lean.outcome() == {**watched.outcome(), "nuisance_cycles": None, "nuisance_causes": {}}
    assert availability([lean]).runs == 0
    with pytest.raises(ValueError, match="shadow"):
        run_encounter(safecase_config, encounter, oracle=True, shadow=False)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_row_with_availability_reads_back_the_same(tmp_path: Path) -> None:
    row = _row("random_encounter", 3, nuisance=5, share=0.8125)
    line = dumps(row.to_json())
    assert json.loads(line)["nuisance_causes"] == {"path end": 1, "zone:CONE": 4}
    assert CampaignRow.from_json(json.loads(line)) == row
    assert row.nuisance_share == pytest.approx(0.1)
    path = tmp_path / "c.jsonl"
    with CampaignLog.open(path, SafecaseConfig()) as log:
        log.add(row)
    with CampaignLog.open(path, SafecaseConfig()) as log:
        assert log.rows == [row]


@pytest.mark.requirement("SR-RUN-8", kind="property", code=["safety/campaign.py"])
@given(
    nuisance=st.none() | st.integers(0, 10_000),
    causes=st.dictionaries(st.text(min_size=1, max_size=20), st.integers(1, 10_000), max_size=5),
    share=st.none() | st.floats(0.0, 10.0),
    closest_m=st.floats(0.0, 50.0) | st.just(float("inf")),
)
def test_every_row_reads_back_from_its_line(
    nuisance: int | None, causes: dict[str, int], share: float | None, closest_m: float
) -> None:
    row = replace(
        _row("random_encounter", 9),
        nuisance_cycles=nuisance,
        nuisance_causes=causes,
        progress_share=share,
        closest_m=closest_m,
    )
    assert CampaignRow.from_json(json.loads(dumps(row.to_json()))) == row


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign.py"])
def test_a_row_without_availability_keys_resumes_without_figures(tmp_path: Path) -> None:
    """A line lacking the availability keys loads (the campaign resumes) with no shadow
    figures: it counts in the contact bound, not in the availability; a malformed value is
    refused naming the file and line."""
    config = SafecaseConfig()
    path = tmp_path / "c.jsonl"
    with CampaignLog.open(path, config) as log:
        log.add(_row("random_encounter", 1, (0.3,)))
    header, line = path.read_text().splitlines()
    short = json.loads(line)
    for key in ("nuisance_cycles", "nuisance_causes", "progress_share"):
        del short[key]
    path.write_text(f"{header}\n{dumps(short)}\n")
    with CampaignLog.open(path, config) as log:
        (old,) = log.rows
        log.add(_row("random_encounter", 2, share=0.5))
    assert (old.nuisance_cycles, old.nuisance_causes, old.progress_share) == (None, {}, None)
    assert old.nuisance_share is None
    with CampaignLog.open(path, config) as log:
        rows = log.rows
    assert contact_bound(rows).violations == 1
    figures = availability(rows)
    assert (figures.runs, figures.cycles, figures.nuisance_cycles) == (1, 50, 4)
    short["nuisance_cycles"] = "many"
    path.write_text(f"{header}\n{dumps(short)}\n")
    with pytest.raises(CampaignError, match=r"c\.jsonl:2: not a campaign row"):
        CampaignLog.open(path, config)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/campaign_stats.py"])
def test_the_availability_figures_per_scenario_and_overall() -> None:
    rows = [
        _row("a", 0, nuisance=4, share=0.5),
        _row("a", 1, nuisance=0, share=1.0),
        _row("b", 0, nuisance=2),
        _row("b", 1, nuisance=None),  # no shadow figures: left out
        failed_row(Encounter("b", 2, 5.0), "boom"),
    ]
    overall = availability(rows)
    assert (overall.runs, overall.cycles, overall.stop_cycles) == (3, 150, 30)
    assert overall.nuisance_share == pytest.approx(6 / 150)
    assert overall.stop_share == pytest.approx(30 / 150)
    assert (overall.oracle_runs, overall.mean_progress_share) == (2, 0.75)
    assert overall.worst_progress_share == 0.5
    assert nuisance_causes(rows) == {"zone:CONE": 4, "path end": 2}
    assert availability_table(rows) == [
        ["a", "2", "20.0 %", "4.0 %", "2", "75.0 %", "50.0 %"],
        ["b", "1", "20.0 %", "4.0 %", "0", "-", "-"],
        ["all", "3", "20.0 %", "4.0 %", "2", "75.0 %", "50.0 %"],
    ]
    unmeasured = [failed_row(Encounter("c", 0, 1.0), "x")]
    empty = availability(unmeasured)
    assert (empty.runs, empty.nuisance_share, empty.mean_progress_share) == (0, 0.0, None)
    assert availability_table(unmeasured)[-1] == ["all", "0", "-", "-", "0", "-", "-"]


def test_the_command_refuses_bad_input(tmp_path: Path) -> None:
    bad = tmp_path / "bad.jsonl"
    bad.write_text("garbage\n")
    result = CliRunner().invoke(app, ["campaign", "--encounters", "1", "--out", str(bad)])
    assert result.exit_code == 2, result.output
    assert "not a campaign file" in result.output
    result = CliRunner().invoke(app, ["campaign", "--encounters", "0", "--out", str(bad)])
    assert result.exit_code == 2
    assert "nothing to run" in result.output
    new = str(tmp_path / "new.jsonl")
    result = CliRunner().invoke(
        app, ["campaign", "--encounters", "1", "--oracle", "--no-shadow", "--out", new]
    )
    assert result.exit_code == 2
    assert "--no-shadow" in result.output
    assert not (tmp_path / "new.jsonl").exists()
    result = CliRunner().invoke(
        app,
        [
            "campaign",
            "--encounters",
            "1",
            "--scheduler",
            "tcp://127.0.0.1:9",
            "--out",
            str(tmp_path / "new.jsonl"),
        ],
    )
    assert result.exit_code == 2, result.output
    assert "tcp://127.0.0.1:9" in result.output


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["evidence/cli/campaign.py"])
def test_ctrl_c_keeps_the_finished_runs_and_says_how_to_resume(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import evidence.cli.campaign as command

    def one_then_interrupted(
        client: object,
        cfg: object,
        plan: list[Encounter],
        log: CampaignLog,
        *args: object,
        **kwargs: object,
    ) -> None:
        log.add(failed_row(plan[0], "E: stands in for a finished run"))
        raise KeyboardInterrupt

    monkeypatch.setattr(command, "_run", one_then_interrupted)
    target = tmp_path / "c.jsonl"
    result = CliRunner().invoke(
        app, ["campaign", "--encounters", "3", "--workers", "1", "--out", str(target)]
    )
    assert result.exit_code == 130, result.output
    assert f"interrupted: 1 of 3 runs are in {target}" in result.output
    assert "resumes" in result.output
    assert len(target.read_text().splitlines()) == 2  # the header and the finished run


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["evidence/cli/campaign.py"])
def test_the_command_runs_reports_and_resumes(tmp_path: Path) -> None:
    target = tmp_path / "c.jsonl"
    args = ["campaign", "--encounters", "2", "--duration", "1", "--workers", "1"]
    first = CliRunner().invoke(
        app, [*args, "--oracle", "--out", str(target), "--plot", str(tmp_path / "p.png")]
    )
    assert first.exit_code == 0, first.output
    assert "Dask dashboard: http" in first.output
    assert "random_encounter" in first.output
    assert "nuisance STOP" in first.output
    assert (tmp_path / "p.png").stat().st_size > 0
    lines = target.read_text().splitlines()
    assert len(lines) == 3
    assert all(json.loads(line)["progress_share"] is not None for line in lines[1:])
    more = CliRunner().invoke(
        app,
        [
            "campaign",
            "--encounters",
            "3",
            "--duration",
            "1",
            "--workers",
            "1",
            "--no-shadow",
            "--out",
            str(target),
        ],
    )
    assert more.exit_code == 0, more.output
    assert "resuming" in more.output
    assert "2 of 3 runs done" in more.output
    lines = target.read_text().splitlines()
    assert len(lines) == 4
    assert json.loads(lines[1])["nuisance_cycles"] is not None
    assert json.loads(lines[3])["progress_share"] is None  # this call ran without --oracle
    assert json.loads(lines[3])["nuisance_cycles"] is None  # ... and without the shadow


@pytest.mark.requirement("SR-TIM-1", kind="example", code=["safety/campaign_stats.py"])
def test_each_timed_run_gives_its_slowest_cycle_as_a_block_maximum() -> None:
    rows = [
        replace(_row("random_encounter", 1), cpu_ms={"p50": 9.0, "p99": 20.0, "max": 31.5}),
        replace(_row("random_encounter", 2), cycles=44),
        failed_row(Encounter("random_encounter", 3, 5.0), "E: y"),
    ]
    maxima, cycles = cpu_block_maxima(rows)
    assert maxima.tolist() == [0.0315, 0.030]
    assert cycles == 44
    empty, none = cpu_block_maxima(rows[2:])
    assert (empty.size, none) == (0, 0)


@pytest.mark.requirement("SR-TIM-1", kind="example", code=["evidence/cli/campaign.py"])
def test_a_finished_campaign_is_reported_with_the_cycle_pwcet(tmp_path: Path) -> None:
    """Twelve finished runs: the command starts no cluster, reports the bound and fits the
    runs' slowest cycles; with nine runs it says the fit needs ten."""
    path = tmp_path / "c.jsonl"
    slowest = [30.0 + 0.7 * i + (i % 3) for i in range(12)]
    with CampaignLog.open(path, SafecaseConfig()) as log:
        for seed, worst in enumerate(slowest):
            log.add(
                replace(
                    _row("random_encounter", seed),
                    cpu_ms={"p50": 10.0, "p99": 20.0, "max": worst},
                )
            )
    args = ["campaign", "--duration", "5", "--out", str(path)]
    result = CliRunner().invoke(app, [*args, "--encounters", "12"])
    assert result.exit_code == 0, result.output
    assert "Dask dashboard" not in result.output
    assert "12 of 12 runs done" in result.output
    text = " ".join(result.output.split())  # rich wraps long lines
    assert "cycle CPU pWCET at 1e-9 per cycle: bound " in text
    assert "the slowest cycle 39.7 ms" in text
    assert "GEV of the slowest cycle of 12 runs, blocks of 50 cycles or more" in text
    fewer = CliRunner().invoke(app, [*args, "--encounters", "9"])
    assert fewer.exit_code == 0, fewer.output
    assert "needs the slowest cycle of at least 10 timed runs (have 9)" in fewer.output
    flat = tmp_path / "flat.jsonl"
    with CampaignLog.open(flat, SafecaseConfig()) as log:
        for seed in range(10):
            log.add(_row("random_encounter", seed))
    same = CliRunner().invoke(
        app, ["campaign", "--duration", "5", "--out", str(flat), "--encounters", "10"]
    )
    assert same.exit_code == 0, same.output
    assert "no fit (GEV: all 10 block maxima are 0.03 s; a tail needs spread)" in " ".join(
        same.output.split()
    )
