"""Closed-loop campaigns on a Dask cluster and the bound on the contact rate (SR-RUN-8).

The campaign runs seeded encounters (every named scenario and random encounters) as tasks on a
real :class:`distributed.LocalCluster` of two worker processes, the same engine ``safecase
campaign`` and ``safecase train`` use (:mod:`pipeline.distributed`). The runs at the head of the
plan have the shadow oracle deciding on their frames, so the evidence shows availability too:
nuisance STOPs as a share of cycles and, for the first of them (every named scenario's under
``certify``), which also run the oracle's own closed loop, our progress over the oracle's; the
rest run without the shadow (``--no-shadow``: the same runs at about 60 % of the CPU), which is
all a contact bound needs. Under ``certify`` and ``certify-full`` it runs 300 encounters, enough
for zero contacts while moving to bound the per-run rate below the configured
``campaign.max_contact_rate`` (1 %) at one-sided 95 %; ``certify-full`` gives every run the
shadow. Under ``ci`` a handful, which still exercises every path and reports the (weak) bound it
supports.

The engine's fault paths run for real on the same cluster: a worker process killed in the
middle of its task (the task is rerun on another worker and its row arrives), a run that
raises (recorded as a failed row, counted as a violation), a resumed campaign (only the
missing runs run), and the same seed giving the same row on a worker as in this process.
"""

from __future__ import annotations

import functools
import os
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from distributed import Client

from evidence.profiles import active_profile, by_profile, certifying
from evidence.record import Recorder
from evidence.wcet import MIN_FIT_POINTS, fit_gev_maxima
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.distributed import TaskFailed, as_done, open_client
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.training.data import RunSpec
from pipeline.training.plan import gather_rows
from safety.campaign import (
    NAMED,
    CampaignLog,
    CampaignRow,
    Encounter,
    encounter_plan,
    failed_row,
    run_campaign,
    run_encounter,
)
from safety.campaign_stats import (
    AVAILABILITY_COLUMNS,
    BOUND_COLUMNS,
    availability,
    availability_table,
    bound_table,
    closest_figure,
    command_mix,
    contact_bound,
    cpu_block_maxima,
    nuisance_causes,
)
from safety.run import run_simulation
from safety.runtime import Runtime

CODE = [
    "safety/campaign.py",
    "safety/campaign_stats.py",
    "pipeline/distributed.py",
    "safety/run.py",
    "safety/availability.py",
]


# Encounters: zero contacts in 300 runs bound the rate below the 1 % target (95 % bound 0.0099).
CERTIFY_RUNS = 300


def _oracle_runs() -> int:
    """How many encounters at the head of the plan also run the oracle's closed loop (it
    costs 1.6 times a row without it: docs/findings/campaigns.md)."""
    return by_profile(ci=2, certify=10, full=30)


def _shadow_runs() -> int:
    """How many encounters at the head of the plan run with the shadow oracle (the rest run
    without it: the shadow costs about 40 % of a run's CPU and no contact depends on it)."""
    return by_profile(ci=len(_plan()), certify=100, full=CERTIFY_RUNS)


def _plan() -> list[Encounter]:
    if certifying():
        named = 2 * len(NAMED)
        return encounter_plan(CERTIFY_RUNS - named, named_seeds=2, duration_s=12.0, first_seed=1000)
    return encounter_plan(5, named_seeds=0, duration_s=4.0, first_seed=1000)


@pytest.fixture(scope="module")
def client() -> Iterator[Client]:
    """A two-worker LocalCluster for the module (processes, one thread each)."""
    with open_client(workers=2) as c:
        yield c


@pytest.mark.requirement("SR-RUN-8", kind="campaign", code=CODE)
def test_the_contact_rate_is_bounded_by_a_campaign(
    safecase_config: SafecaseConfig, client: Client, tmp_path: Path, evidence: Recorder
) -> None:
    config = safecase_config
    plan = _plan()
    with CampaignLog.open(tmp_path / "campaign.jsonl", config) as log:
        run_campaign(client, config, plan[: _oracle_runs()], log, oracle=True)
        run_campaign(client, config, plan[: _shadow_runs()], log)  # resumed without the oracle
        rows = run_campaign(client, config, plan, log, shadow=False)  # the rest, lean
    assert len(rows) == len(plan)
    overall = contact_bound(rows)
    target = config.campaign.max_contact_rate
    evidence.table(
        "contact rate while moving, per scenario (Clopper-Pearson one-sided upper bounds)",
        list(BOUND_COLUMNS),
        bound_table(rows),
        caption=f"{len(rows)} encounters on a 2-worker Dask LocalCluster ({active_profile()} "
        f"profile); target: the 95 % bound below campaign.max_contact_rate = {target}.",
    )
    closest = np.array([r.closest_m for r in rows if np.isfinite(r.closest_m)])
    evidence.counts("commands over the campaign (cycles)", dict(command_mix(rows)))
    evidence.note(
        f"closest approach over {closest.size} runs: min {closest.min():.2f} m, "
        f"median {np.median(closest):.2f} m; runs that touched anything (moving or not): "
        f"{sum(r.contacts > 0 for r in rows)}."
    )
    evidence.plot("closest approach per run", closest_figure(rows))
    maxima, cycles = cpu_block_maxima(rows)
    if maxima.size >= MIN_FIT_POINTS:  # 300 runs under certify; a handful under ci
        fit = fit_gev_maxima(maxima, block_size=cycles)  # EvidenceError only without spread
        evidence.note(
            f"cycle thread CPU time, the campaign as block maxima (SR-TIM-1): the slowest "
            f"cycle of each of {fit.n_fit} runs ({cycles} cycles or more each) is "
            f"{maxima.max() * 1e3:.1f} ms at most; GEV shape {fit.shape_xi:+.3f}, KS p = "
            f"{fit.ks_pvalue:.2f}; pWCET at 1e-9 per cycle {fit.pwcet_s * 1e3:.1f} ms. CPU "
            "time of a cycle on workers sharing two cores, not the latency of a robot's "
            "computer: the WCET analysis of SR-TIM-1 bounds that."
        )
    evidence.table(
        "availability per scenario: nuisance STOPs against the shadow oracle, progress vs oracle",
        list(AVAILABILITY_COLUMNS),
        availability_table(rows),
        caption="STOP and nuisance STOP (we stop, the oracle deciding on the same frame would "
        "go on) as shares of all cycles; progress vs oracle: our arc length over the oracle's "
        "own closed loop of the same seed, over the time both lasted (mean and least over the "
        f"runs that ran it, the first {_oracle_runs()} of the plan). Only the first "
        f"{_shadow_runs()} runs of the plan had the shadow; the rest count in the contact "
        "bound alone.",
    )
    evidence.counts("what set our command in the nuisance STOP cycles", dict(nuisance_causes(rows)))
    figures = availability(rows)
    assert figures.runs == _shadow_runs()
    assert figures.oracle_runs == _oracle_runs()
    assert figures.nuisance_cycles <= figures.stop_cycles
    assert overall.errors == 0, [r.error for r in rows if r.error]
    assert overall.violations == 0, [r.encounter.key for r in rows if r.moving_contacts_mps]
    if certifying():
        assert overall.upper_95 < target, f"95 % bound {overall.upper_95:.4f} >= {target}"


def _die_once(marker: str) -> str:
    """Kill this worker process the first time (no result, no exception: the process is
    gone), answer the second time."""
    path = Path(marker)
    if not path.exists():
        path.write_text(str(os.getpid()))
        os._exit(1)
    return f"answered by {os.getpid()} after {path.read_text()} died"


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["pipeline/distributed.py"])
def test_a_killed_worker_loses_no_task(client: Client, tmp_path: Path) -> None:
    marker = tmp_path / "died"
    (outcome,) = list(as_done(client, _die_once, [str(marker)]))
    assert marker.exists(), "the first attempt did not run"
    assert isinstance(outcome.result, str), outcome.result
    assert outcome.result.startswith("answered by")
    assert marker.read_text() not in outcome.result.split(" after ")[0]


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_a_run_that_raises_is_recorded_and_counted(
    safecase_config: SafecaseConfig, client: Client, tmp_path: Path
) -> None:
    bad = Encounter("no_such_scenario", 0, 1.0)
    good = Encounter("random_encounter", 7, 1.0)
    with CampaignLog.open(tmp_path / "c.jsonl", safecase_config) as log:
        rows = run_campaign(client, safecase_config, [bad, good], log)
    by_key = {r.encounter.key: r for r in rows}
    assert "no_such_scenario" in str(by_key[bad.key].error)
    assert by_key[good.key].error is None
    assert by_key[good.key].cycles > 0
    bound = contact_bound(rows)
    assert (bound.runs, bound.violations, bound.errors) == (2, 1, 1)
    # the failure is in the file too: a resumed campaign does not run it again silently
    with CampaignLog.open(tmp_path / "c.jsonl", safecase_config) as again:
        assert again.done() == {bad.key, good.key}
        assert again.rows[0].error == rows[0].error


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_a_resumed_campaign_runs_only_what_is_missing(
    safecase_config: SafecaseConfig, client: Client, tmp_path: Path
) -> None:
    plan = encounter_plan(3, duration_s=1.0, first_seed=40)
    path = tmp_path / "c.jsonl"
    kept = failed_row(plan[1], "marker: kept from the first call")
    with CampaignLog.open(path, safecase_config) as log:
        log.add(kept)
    with path.open("a") as handle:
        handle.write('{"scenario": "random_enc')  # a line cut short by a kill
    with CampaignLog.open(path, safecase_config) as log:
        rows = run_campaign(client, safecase_config, plan, log)
    assert rows[0] == kept  # not rerun
    assert sorted(r.encounter for r in rows) == sorted(plan)
    assert all(r.error is None for r in rows[1:])
    assert len(path.read_text().splitlines()) == 1 + len(plan)


@pytest.mark.requirement("SR-RUN-8", kind="example", code=CODE)
def test_the_same_seed_gives_the_same_row_on_any_worker(
    safecase_config: SafecaseConfig, client: Client
) -> None:
    encounter = Encounter("crossing_pedestrian", 3, 2.0)
    here = run_encounter(safecase_config, encounter)
    remote = [
        d.result
        for d in as_done(
            client, _run_with_config, [(safecase_config, encounter), (safecase_config, encounter)]
        )
    ]
    assert not any(isinstance(r, TaskFailed) for r in remote), remote
    for row in remote:
        assert not isinstance(row, TaskFailed)
        assert row.outcome() == here.outcome()


def _run_with_config(args: tuple[SafecaseConfig, Encounter]) -> CampaignRow:
    return run_encounter(*args)


@pytest.mark.requirement("SR-CLS-3", kind="example", code=["pipeline/training/plan.py"])
def test_training_data_on_the_cluster_equals_one_process(safecase_config: SafecaseConfig) -> None:
    plan = [RunSpec("crossing_pedestrian", 5, 2.0), RunSpec("random_encounter", 6, 2.0)]
    one = gather_rows(safecase_config, plan, workers=1)
    two = gather_rows(safecase_config, plan, workers=2)
    assert one.features.shape[0] > 0
    for name in ("features", "label", "run", "stamp_s", "track_id", "object_id", "range_m"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name), err_msg=name)
    assert one.runs == two.runs


@pytest.mark.requirement("SR-RUN-8", kind="measurement", code=["pipeline/distributed.py"])
def test_throughput_with_one_and_two_workers(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    """The same encounters in this process, on one worker and on two: runs per second and the
    per-task cost of going through Dask (cluster start-up excluded, reported beside)."""
    n, length = (16, 6.0) if certifying() else (2, 1.0)
    plan = encounter_plan(n, duration_s=length, first_seed=2000)
    start = time.perf_counter()
    for encounter in plan:
        run_encounter(safecase_config, encounter)
    local_s = time.perf_counter() - start
    rows = [["this process", "-", f"{local_s:.1f}", f"{n / local_s:.2f}", "1.00"]]
    for workers in (1, 2):
        start = time.perf_counter()
        with open_client(workers=workers) as c:
            up_s = time.perf_counter() - start
            start = time.perf_counter()
            done = list(as_done(c, functools.partial(run_encounter, safecase_config), plan))
            run_s = time.perf_counter() - start
        assert not any(isinstance(d.result, TaskFailed) for d in done)
        rows.append(
            [
                f"LocalCluster, {workers} worker(s)",
                f"{up_s:.1f}",
                f"{run_s:.1f}",
                f"{n / run_s:.2f}",
                f"{local_s / run_s:.2f}",
            ]
        )
    evidence.table(
        "campaign throughput: the same encounters in one process and on Dask",
        ["where", "cluster start [s]", "runs [s]", "runs per second", "speed-up"],
        rows,
        caption=f"{n} random encounters of {length:g} s ({active_profile()} profile), wall "
        f"clock on this machine (os.cpu_count() = {os.cpu_count()}); the first worker run "
        "includes loading the classifier once per worker. Ideal speed-up with two workers: 2.",
    )


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["safety/obstacles.py"])
def test_the_contact_the_campaign_found_stays_fixed(safecase_config: SafecaseConfig) -> None:
    """random_encounter seed 1028: a forklift beside racking is clustered with it into a cluster
    too large to keep; its points taken as static structure let the robot drive into it at
    0.16 m/s. Loose points closing at the fastest class's speed (the default) keep it stopped."""
    encounter = Encounter("random_encounter", 1028, 12.0)
    assert run_encounter(safecase_config, encounter).moving_contacts_mps == ()
    static = safecase_config.model_copy(
        update={"runtime": safecase_config.runtime.model_copy(update={"loose_points": "static"})}
    )
    assert run_encounter(static, encounter).moving_contacts_mps != ()


@pytest.mark.requirement("SR-RUN-8", kind="measurement", code=["safety/campaign.py"])
def test_what_the_shadow_and_the_oracle_cost(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    """CPU time of one encounter run alone (as ``safecase run`` does), as a campaign row (our
    run with the shadow oracle deciding on every frame) and as a row with ``--oracle`` (the
    oracle's own closed loop of the same seed too), the variants interleaved per encounter."""
    config = safecase_config
    n, length = (4, 12.0) if certifying() else (1, 1.0)
    plan = encounter_plan(n, duration_s=length, first_seed=1000)
    model = Classifier.from_config(config.classify)
    run_encounter(config, Encounter("random_encounter", 0, 0.5))  # loads the campaign's model
    cpu_s = {"alone": 0.0, "row": 0.0, "row with --oracle": 0.0}
    for e in plan:
        start = time.thread_time()
        sim = make_simulation(config, e.scenario, e.seed, e.duration_s)
        run_simulation(config, sim, runtime=Runtime(config, classifier=model))
        cpu_s["alone"] += time.thread_time() - start
        start = time.thread_time()
        run_encounter(config, e)
        cpu_s["row"] += time.thread_time() - start
        start = time.thread_time()
        run_encounter(config, e, oracle=True)
        cpu_s["row with --oracle"] += time.thread_time() - start
    evidence.table(
        "what a campaign row costs: CPU time per encounter",
        ["run", "CPU per encounter [s]", "against the run alone"],
        [[k, f"{v / n:.2f}", f"{v / cpu_s['alone']:.2f}"] for k, v in cpu_s.items()],
        caption=f"{n} random encounter(s) of {length:g} s ({active_profile()} profile), thread "
        "CPU time in one process on this machine.",
    )
    assert cpu_s["row"] < cpu_s["row with --oracle"]
