"""The runtime in closed loop, under faults, and on its audit log (SR-RUN-1, -2, -4).

SR-RUN-1 is a campaign: every named scenario (and seeded random encounters) runs with the
runtime deciding after every scan and the simulated robot obeying through its actuation
latency; a contact while the robot moves is a violation (passive safety). The same contact
detector is shown to fire on the default scenario without the governor, so a silent campaign
is not a blind one.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import active_profile, by_profile, certifying, examples
from evidence.record import Recorder, current
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.sources.sim.ego import ConstantSpeed
from pipeline.sources.sim.scenarios import SCENARIOS, make_simulation
from pipeline.types import Action, RadarDetections, Scan
from properties.ahead import ahead
from safety.audit.replay import replay
from safety.audit.verify import verify_log
from safety.run import RunSummary, contact_speeds, run_scenario, run_simulation
from safety.run_plot import run_figure
from safety.runtime import STAGES, CycleInput, Runtime

CODE = ["safety/runtime.py", "safety/run.py", "safety/geometry/path.py"]


def _runs() -> list[tuple[str, int, float]]:
    named = [n for n in SCENARIOS if n != "random_encounter"]
    if certifying():
        seeds, randoms = by_profile(ci=(0, 0), certify=(2, 6), full=(3, 12))
        return [
            *((n, seed, 20.0) for n in named for seed in range(seeds)),
            *(("random_encounter", seed, 20.0) for seed in range(100, 100 + randoms)),
        ]
    return [*((n, 0, 15.0) for n in named), *(("random_encounter", s, 15.0) for s in (1, 2))]


@pytest.fixture(scope="module")
def classifier(safecase_config: SafecaseConfig) -> Classifier:
    """The configured model, loaded once for the module."""
    return Classifier.from_config(safecase_config.classify)


@pytest.mark.requirement("SR-RUN-1", kind="campaign", code=CODE)
@ahead
def test_closed_loop_passive_safety(
    safecase_config: SafecaseConfig, classifier: Classifier, evidence: Recorder
) -> None:
    config = safecase_config
    rows, moving = [], []
    shown: RunSummary | None = None
    for name, seed, duration in _runs():
        sim = make_simulation(config, name, seed, duration)
        summary = run_simulation(config, sim, runtime=Runtime(config, classifier=classifier))
        result = summary.sim
        assert result is not None
        speeds = contact_speeds(result)
        moving += [f"{name} seed {seed}: {v:.3f} m/s" for v in speeds if v > 0.0]
        rows.append(
            [
                name,
                seed,
                ", ".join(f"{k} {v}" for k, v in sorted(summary.actions.items())),
                "none" if not speeds.size else " ".join(f"{v:.2f}" for v in speeds),
                f"{float(np.min(result.min_separation_m, initial=np.inf)):.2f}",
                f"{result.ego_log['arc_m'][-1]:.1f} / {result.ego_spec.route.length_m:.0f}",
            ]
        )
        evidence.count("runs", "with a contact" if speeds.size else "without contact")
        evidence.count("cycles", "all", summary.cycles)
        if shown is None:
            shown = summary
    evidence.table(
        "closed-loop runs (runtime deciding, robot obeying through its actuation latency)",
        [
            "scenario",
            "seed",
            "commands",
            "robot speed at contact [m/s]",
            "closest [m]",
            "progress [m]",
        ],
        rows,
        caption=f"{len(rows)} runs ({active_profile()} profile); a contact at 0 m/s is an "
        "object driving into the stopped robot (passive safety holds).",
    )
    assert shown is not None
    evidence.plot("default scenario in closed loop", run_figure(shown))
    assert not moving, f"contact while moving: {moving}"


@pytest.mark.requirement("SR-RUN-1", kind="example", code=["pipeline/sources/sim/simulation.py"])
def test_the_contact_detector_fires_without_the_governor(safecase_config: SafecaseConfig) -> None:
    """The campaign's yardstick can fail: at a constant 1 m/s the default scenario's forklift
    is hit with the robot moving."""
    sim = make_simulation(safecase_config, duration_s=15.0)
    result = sim.run(ConstantSpeed(1.0))
    speeds = contact_speeds(result)
    assert speeds.size, "no contact at a constant 1 m/s"
    assert speeds.max() > 0.5, speeds
    assert RunSummary(sim.name, sim=result).moving_contacts >= 1  # `safecase run` exits 1
    current().note(f"without the governor: contact at {speeds.max():.2f} m/s")


@pytest.fixture(scope="module")
def scans(safecase_config: SafecaseConfig) -> list[Scan]:
    """Two seconds of the default scenario's scans."""
    return list(make_simulation(safecase_config, duration_s=2.0).scans())


FAULTS = (*STAGES, "no scan", "nan pose", "radar while moving")


@pytest.mark.requirement("SR-RUN-2", kind="property", code=["safety/runtime.py"])
@settings(max_examples=examples(40), deadline=None)
@given(fault=st.sampled_from(FAULTS), at=st.integers(1, 12))
def test_a_failing_stage_or_bad_input_stops_and_the_next_cycle_recovers(
    safecase_config: SafecaseConfig,
    classifier: Classifier,
    scans: list[Scan],
    fault: str,
    at: int,
) -> None:
    config = safecase_config
    rt = Runtime(config, classifier=classifier)

    def broken(stage: str) -> None:
        if stage == fault:
            raise RuntimeError(f"injected failure in {stage}")

    outs = []
    for i, scan in enumerate(scans[: at + 2]):
        hit = i == at
        pose = (0.0, 0.0, 0.0)
        chosen: Scan | None = None if hit and fault == "no scan" else scan
        radar = None
        if hit and fault == "nan pose":
            pose = (float("nan"), 0.0, 0.0)
        elif hit and fault == "radar while moving":
            pose = (0.5, 0.0, 0.0)
            radar = RadarDetections(
                np.array([scan.stamp_s]), np.array([3.0]), np.array([0.0]), np.array([-1.0])
            )
        base = CycleInput.standing(chosen, scan.stamp_s + 0.1, config, charge_s=0.02)
        failing = broken if hit and fault in STAGES else None
        outs.append(rt.step(replace(base, robot_pose=pose, radar=radar, fault=failing)))
    failed, after = outs[at], outs[at + 1]
    assert failed.command.action is Action.STOP
    stage_reasons = [r for r in failed.command.reasons if r.startswith("stage:")]
    assert stage_reasons, failed.command.reasons
    if fault in STAGES:
        assert stage_reasons[0].startswith(f"stage:{fault}: RuntimeError: injected"), stage_reasons
    assert not any(r.startswith("stage:") for r in after.command.reasons), after.command
    current().count("faults", fault)


@pytest.mark.requirement(
    "SR-RUN-4", kind="example", code=["safety/run.py", "safety/audit/replay.py"]
)
def test_a_closed_loop_run_is_audited_and_replays_bit_for_bit(
    safecase_config: SafecaseConfig, tmp_path: Path, evidence: Recorder
) -> None:
    log = tmp_path / "run.jsonl"
    summary = run_scenario(safecase_config, "crossing_pedestrian", 0, 4.0, audit_path=log)
    verdict = verify_log(log)
    assert verdict.ok, verdict
    report = replay(log)
    assert report.ok, report.mismatches
    assert report.n_cycles == summary.cycles == 40
    header = report.verification.header
    assert header is not None
    assert header["model_hash"] == Classifier.from_config(safecase_config.classify).model_sha256
    assert (
        header["latency"]["perception_latency_s"] == safecase_config.stopping.perception_latency_s
    )
    evidence.note(f"{report.n_cycles} cycles replayed exactly; {verdict.describe()}")


@pytest.mark.requirement(
    "SR-RUN-4", kind="example", code=["safety/run.py", "pipeline/sources/serial/source.py"]
)
def test_the_runtime_reads_an_emulated_scanner_over_a_pty(
    safecase_config: SafecaseConfig, tmp_path: Path
) -> None:
    from pipeline.config import overridden
    from pipeline.sources.serial.source import EmulatedSource
    from safety.run import run_audited

    bench = overridden(
        safecase_config, {"sim": {"ego_speed_mps": 0.0, "lidar_device": "rplidar_a2"}}
    )
    sim = make_simulation(bench, "crossing_pedestrian", 1, 10.0)
    log = tmp_path / "device.jsonl"
    driver = bench.driver.model_copy(update={"protocol": "rplidar", "port_url": "emulated"})
    source = EmulatedSource(driver, bench.track.frame_period_s, sim.scans(), 10.0)
    outs = list(run_audited(bench, source, audit_path=log, max_scans=12))
    with_scan = [o for o in outs if o.record.inputs.get("scan")]
    assert len(with_scan) == 12
    assert any(o.command.action is not Action.STOP for o in with_scan)
    report = replay(log)
    assert report.ok, report.mismatches
    assert report.n_cycles == len(outs)
