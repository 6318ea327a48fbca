"""The campaign file and the contact-rate bound, without a cluster (SR-RUN-8).

The bound is checked against an independent reference: the Clopper-Pearson upper limit is by
definition the ``level`` quantile of Beta(k + 1, n - k) (``scipy.stats.beta``), and with no
violation ``1 - (1 - level) ** (1 / n)`` in closed form.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import beta
from typer.testing import CliRunner

from evidence.cli.main import app
from pipeline.config import SafecaseConfig
from safety.campaign import CampaignError, CampaignLog, CampaignRow, Encounter, failed_row
from safety.campaign_stats import by_scenario, contact_bound, upper_limit

CODE = ["safety/campaign.py", "safety/campaign_stats.py"]


def _row(scenario: str, seed: int, moving: tuple[float, ...] = ()) -> CampaignRow:
    return CampaignRow(
        Encounter(scenario, seed, 5.0),
        cycles=50,
        commands={"PROCEED": 40, "STOP": 10},
        contacts=len(moving),
        moving_contacts_mps=moving,
        closest_m=1.5,
        progress_m=3.0,
        route_m=30.0,
        cpu_ms={"p50": 10.0, "p99": 20.0, "max": 30.0},
    )


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


def test_the_command_refuses_bad_input(tmp_path: Path) -> None:
    bad = tmp_path / "bad.jsonl"
    bad.write_text("garbage\n")
    result = CliRunner().invoke(app, ["campaign", "--encounters", "1", "--out", str(bad)])
    assert result.exit_code == 2, result.output
    assert "not a campaign file" in result.output
    result = CliRunner().invoke(app, ["campaign", "--encounters", "0", "--out", str(bad)])
    assert result.exit_code == 2
    assert "nothing to run" in result.output
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
def test_the_command_runs_reports_and_resumes(tmp_path: Path) -> None:
    target = tmp_path / "c.jsonl"
    args = ["campaign", "--encounters", "2", "--duration", "1", "--workers", "1"]
    first = CliRunner().invoke(
        app, [*args, "--out", str(target), "--plot", str(tmp_path / "p.png")]
    )
    assert first.exit_code == 0, first.output
    assert "Dask dashboard: http" in first.output
    assert "random_encounter" in first.output
    assert (tmp_path / "p.png").stat().st_size > 0
    assert len(target.read_text().splitlines()) == 3
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
            "--out",
            str(target),
        ],
    )
    assert more.exit_code == 0, more.output
    assert "resuming" in more.output
    assert "2 of 3 runs done" in more.output
    assert len(target.read_text().splitlines()) == 4
