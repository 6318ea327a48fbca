"""Cycle latency against the stopping proof's budget, and the deadline monitor (SR-TIM-1, -2).

SR-TIM-1 measures the runtime's whole cycle (:class:`safety.runtime.Runtime`: points ->
cluster -> track -> features -> classify -> fusion -> predict -> envelopes -> path clearance ->
costmap -> monitors and decision) on simulated scans of every named scenario. Each scenario
run has its own pipeline (its own tracker), and the order in which the pipelines take their
next cycle is drawn at random (seeded): the workload mix stays realistic while consecutive
samples come from different scenarios, which is what extreme value theory needs
(independent, identically distributed cycles). Both the wall-clock latency and the thread CPU
time (execution time without preemption by other processes) are analysed; the measured bound
plus one scan period is fed through the stopping model's latency seam, and the margin to the
processing budget (``stopping.perception_latency_s`` minus one scan period) is reported.
Timings on the shared 2-core machine are noisy; the wall-clock tail is reported, the
execution-time pWCET is the bound.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import certifying, examples
from evidence.record import Recorder, current
from evidence.wcet import PwcetReport, exceedance_plot, measured_latency_bound, pwcet
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.sources.sim.scenarios import SCENARIOS, make_simulation
from pipeline.types import Action, Command, Scan
from properties.smt import prove
from properties.stopping_obligations import tier_obligation
from safety.audit.log import AuditWriter
from safety.audit.replay import replay
from safety.model.monitors import Observation, combine, run_monitors
from safety.model.stopping import StoppingParams, Tier
from safety.runtime import CycleInput, Runtime

TIMING = ["evidence/wcet.py", "safety/runtime.py"]
DEADLINE = ["safety/model/monitors.py", "safety/model/decision.py"]


def _scenario_scans(config: SafecaseConfig, duration_s: float) -> list[list[Scan]]:
    runs = []
    for name in SCENARIOS:
        sim = make_simulation(config, name, seed=11, duration_s=duration_s)
        runs.append(list(sim.scans()))
    return runs


def _measure(
    config: SafecaseConfig, runs: list[list[Scan]], n_cycles: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, dict[str, list[float]], list[str]]:
    period = 1.0 / config.sim.scan_rate_hz
    classifier = Classifier.from_config(config.classify)  # loaded once, shared by the runs
    cycles = [Runtime(config, classifier=classifier) for _ in runs]
    position = [0] * len(runs)
    wall, cpu = np.empty(n_cycles), np.empty(n_cycles)
    stages: dict[str, list[float]] = {}
    actions = []
    for i in range(n_cycles):
        k = int(rng.integers(len(runs)))
        if position[k] == len(runs[k]):
            cycles[k], position[k] = Runtime(config, classifier=classifier), 0  # starts over
        scan = runs[k][position[k]]
        position[k] += 1
        start = time.perf_counter_ns()
        result = cycles[k].step(CycleInput.standing(scan, scan.stamp_s + period, config))
        wall[i] = (time.perf_counter_ns() - start) * 1e-9
        cpu[i] = result.cpu_s
        for name, value in result.wall_s.items():
            stages.setdefault(name, []).append(value)
        actions.append(result.command.action.value)
    return wall, cpu, stages, actions


def _table(evidence: Recorder, name: str, report: PwcetReport, budget_s: float) -> None:
    s, gev, gpd, iid = report.stats, report.gev, report.gpd, report.iid
    ms = 1e3
    evidence.table(
        name,
        ["figure", "value"],
        [
            ["samples", s.n],
            [
                "p50 / p99 / max [ms]",
                f"{s.p50_s * ms:.3f} / {s.p99_s * ms:.3f} / {s.max_s * ms:.3f}",
            ],
            [
                f"GEV (block {gev.block_size}, {gev.n_fit} maxima): xi, pWCET [ms]",
                f"{gev.shape_xi:+.3f}, {gev.pwcet_s * ms:.4g}",
            ],
            [
                "GEV goodness of fit: KS p, AD p (refit MC)",
                f"{gev.ks_pvalue:.3f}, {gev.ad_pvalue:.3f}",
            ],
            [
                f"GPD (over {gpd.threshold_s * ms:.3f} ms, {gpd.n_fit} excesses): xi, pWCET [ms]",
                f"{gpd.shape_xi:+.3f}, {gpd.pwcet_s * ms:.4g}",
            ],
            [
                "GPD goodness of fit: KS p, AD p (refit MC)",
                f"{gpd.ks_pvalue:.3f}, {gpd.ad_pvalue:.3f}",
            ],
            [
                "i.i.d.: lag-1 autocorrelation, runs test p, halves KS p",
                f"{iid.lag1_autocorr:+.3f}, {iid.runs_pvalue:.3g}, {iid.halves_pvalue:.3g}",
            ],
            [f"bound at {report.exceedance_prob:g}/cycle [ms]", f"{report.bound_s * ms:.4g}"],
            ["budget: perception_latency_s - scan period [ms]", f"{budget_s * ms:g}"],
            ["margin [ms]", f"{(budget_s - report.bound_s) * ms:.4g}"],
        ],
        caption="pWCET: largest of the GEV and GPD estimates and the observed maximum.",
    )


@dataclass(frozen=True)
class Measurement:
    """Latency samples [s] of the runtime cycle, per cycle and per stage."""

    wall_s: np.ndarray
    cpu_s: np.ndarray
    stages_s: dict[str, list[float]]
    actions: list[str]
    n_scenarios: int


@pytest.fixture(scope="module")
def measurement(safecase_config: SafecaseConfig) -> Measurement:
    """One measurement run shared by the SR-TIM-1 and SR-TIM-4 tests."""
    runs = _scenario_scans(safecase_config, duration_s=6.0)
    rng = np.random.default_rng(2024)
    _measure(safecase_config, runs, 200, rng)  # warm caches and imports, not recorded
    # The whole chain costs ~17 ms a cycle here: certify measures 6000 cycles, not 24,000.
    n_cycles = min(examples(2400), 6000)
    wall, cpu, stages, actions = _measure(safecase_config, runs, n_cycles, rng)
    return Measurement(wall, cpu, stages, actions, len(runs))


def processing_budget_s(config: SafecaseConfig) -> float:
    """What the stopping proof's perception term leaves for processing [s]: a scan stamped at
    its first beam is one scan period old when its revolution completes (SR-STOP-5)."""
    return config.stopping.perception_latency_s - config.track.frame_period_s


@pytest.mark.requirement("SR-TIM-1", kind="measurement", code=TIMING)
def test_cycle_latency_within_the_stopping_budget(
    safecase_config: SafecaseConfig, measurement: Measurement, evidence: Recorder
) -> None:
    budget = processing_budget_s(safecase_config)
    reports = {}
    for clock, samples in (
        ("wall clock", measurement.wall_s),
        ("thread CPU time", measurement.cpu_s),
    ):
        report = pwcet(samples)
        reports[clock] = report
        evidence.samples(f"cycle latency ({clock})", samples * 1e3, "ms")
        _table(evidence, f"scan-to-decision latency, {clock}", report, budget)
        evidence.plot(
            f"exceedance, {clock}",
            exceedance_plot(samples, report, budget_s=budget, title=f"cycle latency ({clock})"),
            caption=(
                f"{samples.size} cycles over {measurement.n_scenarios} scenarios; dotted: "
                f"{report.exceedance_prob:g} per cycle"
            ),
        )
    evidence.table(
        "per-stage wall-clock time",
        ["stage", "p50 [ms]", "p99 [ms]", "max [ms]"],
        [
            [k, *(f"{np.percentile(v, q) * 1e3:.3f}" for q in (50, 99)), f"{max(v) * 1e3:.3f}"]
            for k, v in measurement.stages_s.items()
        ],
    )
    actions = measurement.actions
    evidence.counts("commands", {a: actions.count(a) for a in sorted(set(actions))})
    bound, provenance = measured_latency_bound(
        measurement.cpu_s, what="runtime scan-to-decision latency", clock="thread CPU time"
    )
    # The proof's perception term is the data's age at decision: the scan's own period plus
    # the measured processing bound.
    params = StoppingParams.from_config(
        safecase_config,
        perception_latency_s=safecase_config.track.frame_period_s + bound,
        latency_source=provenance["latency_source"],
    )
    evidence.provenance("timing.measured_latency_bound", provenance)
    # The seam end to end: the margin tiers proved again with the measured latency term.
    for tier in Tier:
        prove(tier_obligation(params.exact(), tier)).attach(required=False)
    wall = reports["wall clock"].stats
    evidence.note(
        f"Margin of the wall-clock p99 to stopping.perception_latency_s: "
        f"{(budget - wall.p99_s) * 1e3:.3f} ms (p99 {wall.p99_s * 1e3:.3f} ms, max "
        f"{wall.max_s * 1e3:.3f} ms, budget {budget * 1e3:g} ms = perception latency minus one "
        "scan period). The whole runtime chain with the committed classifier; the robot "
        "stands (tracking in the robot frame). The wall clock includes preemption by other "
        "processes on this shared 2-core machine; the pWCET (SR-TIM-4) is estimated from "
        "thread CPU time."
    )
    assert reports["thread CPU time"].bound_s == bound
    assert wall.p99_s <= budget, wall


@pytest.mark.requirement("SR-TIM-4", kind="measurement", code=TIMING)
def test_pwcet_within_the_stopping_budget(
    safecase_config: SafecaseConfig, measurement: Measurement, evidence: Recorder
) -> None:
    budget = processing_budget_s(safecase_config)
    gof_mc = 999 if certifying() else 99
    report = pwcet(measurement.cpu_s, gof_mc=gof_mc, seed=7)
    _table(evidence, "pWCET of thread CPU time with Monte Carlo goodness of fit", report, budget)
    iid = report.iid
    problems = []
    if abs(iid.lag1_autocorr) > 0.1 or iid.runs_pvalue < 0.01 or iid.halves_pvalue < 0.01:
        problems.append(
            f"samples not i.i.d. (lag-1 autocorrelation {iid.lag1_autocorr:+.2f}, runs p "
            f"{iid.runs_pvalue:.2g}, halves KS p {iid.halves_pvalue:.2g})"
        )
    for fit in (report.gev, report.gpd):
        if not fit.fit_ok:
            problems.append(f"{fit.method.upper()} rejected (AD p {fit.ad_pvalue:.3f})")
    if problems:
        # No estimate from data that break EVT's premises: this is no evidence either way.
        evidence.note("EVT conditions not met on this machine: " + "; ".join(problems))
        pytest.skip(
            "EVT conditions not met (re-measure on an idle machine): " + "; ".join(problems)
        )
    assert report.bound_s <= budget, (report.bound_s, budget)


@pytest.mark.requirement("SR-TIM-2", kind="property", code=DEADLINE)
@settings(max_examples=examples(300))
@given(
    duration=st.one_of(st.floats(0.0, 1.0), st.sampled_from([float("nan"), float("inf")])),
    near=st.integers(-3, 3),
    governor=st.sampled_from(["PROCEED", "SLOW", "STOP"]),
)
def test_deadline_miss_stops(
    safecase_config: SafecaseConfig, duration: float, near: int, governor: str
) -> None:
    m = safecase_config.monitors
    if near:
        duration = float(np.nextafter(m.cycle_deadline_s, np.inf if near > 0 else -np.inf))
    obs = Observation(now_s=10.0, scan_stamp_s=9.9, cycle_duration_s=duration)
    command = {
        "PROCEED": Command(Action.PROCEED, 1.0, 10.0),
        "SLOW": Command(Action.SLOW, 0.5, 10.0, ("near",)),
        "STOP": Command(Action.STOP, 0.0, 10.0, ("close",)),
    }[governor]
    verdicts = run_monitors(obs, m)
    final = combine(command, verdicts, stamp_s=10.0, min_moving_mps=0.05)
    missed = not duration <= m.cycle_deadline_s
    deadline = next(v for v in verdicts if v.monitor == "deadline")
    if missed:
        assert final.action is Action.STOP
        assert any(r.startswith("deadline: ") for r in final.reasons), final
    else:
        assert deadline.action is Action.PROCEED
        assert final == command
    current().count("cycles", "missed" if missed else "within deadline")


@pytest.mark.requirement("SR-TIM-2", kind="example", code=[*DEADLINE, "safety/audit/log.py"])
def test_a_stalled_stage_stops_and_the_log_says_why(
    safecase_config: SafecaseConfig, tmp_path: Path
) -> None:
    sim = make_simulation(safecase_config, "crossing_pedestrian", seed=3, duration_s=1.0)
    scans = list(sim.scans())
    log = tmp_path / "stall.log"
    with AuditWriter(log, safecase_config, model_hash=None) as writer:
        cycle = Runtime(safecase_config, writer=writer)
        over = safecase_config.monitors.cycle_deadline_s * 1.5
        # Each cycle is charged 20 ms (a simulated clock) so only the stall can miss the
        # deadline, whatever the load on this machine.
        results = [
            cycle.step(
                CycleInput.standing(
                    scan,
                    scan.stamp_s + 0.1,
                    safecase_config,
                    delay_s=over if i == 4 else 0.0,
                    charge_s=0.02,
                )
            )
            for i, scan in enumerate(scans)
        ]
    stalled = results[4].command
    assert stalled.action is Action.STOP
    assert any("deadline: cycle took" in r for r in stalled.reasons)
    line = log.read_text().splitlines()[5]
    assert "deadline: cycle took" in line
    report = replay(log)
    assert report.ok, report.mismatches
    current().note(f"stalled cycle: {stalled.reasons[-1]}")
    flagged = [any("deadline" in r for r in x.command.reasons) for x in results]
    assert flagged == [i == 4 for i in range(len(results))]
