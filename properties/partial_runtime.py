"""The stages that exist today chained into one timed, audited cycle (SR-TIM-1, SR-AUD-*).

points -> cluster -> track -> fusion -> governor -> monitors, one call per scan, each stage
timed, the decision taken by :func:`safety.decision.decide` and written to an audit log. This
is the measurement harness for the latency evidence and the source of realistic audit logs for
the AUD properties until the real runtime loop (safety/runtime.py) lands; the classifier,
prediction and envelope stages are missing, so the governor's free distance is a stand-in: the
straight-line clearance between the robot's bounding circle and each object's (conservative:
objects behind the robot count too), with the worst class's closing speed.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.cluster import cluster_points
from pipeline.config import SafecaseConfig
from pipeline.fusion import fuse
from pipeline.points import scan_to_points
from pipeline.sim.objects import ObjectKind
from pipeline.sim.truth import KIND_NAMES, ScanTruth
from pipeline.track.tracker import Detections, Tracker
from pipeline.types import (
    Command,
    DriverHealth,
    FusedTracks,
    RadarDetections,
    Scan,
    ThermalDetections,
    TrackStatus,
)
from safety.audit import AuditWriter, BackgroundAuditWriter, CycleRecord, summarize
from safety.decision import Decision, GovernorInputs, decide
from safety.governor import Governor
from safety.monitors import Observation, Verdict
from safety.stopping import StoppingParams

__all__ = ["PERSON_RADIUS_M", "CycleResult", "PartialCycle", "thermal_from_truth"]

PERSON_RADIUS_M = 0.3
_LIVE = (TrackStatus.TENTATIVE, TrackStatus.CONFIRMED, TrackStatus.LOST)


@dataclass(frozen=True, slots=True)
class CycleResult:
    """One cycle: the final command, per-stage wall-clock and thread-CPU times [s]."""

    command: Command
    decision: Decision
    wall_s: dict[str, float]
    cpu_s: float
    record: CycleRecord


class PartialCycle:
    """The partial runtime cycle over one configuration (see the module docstring)."""

    def __init__(
        self,
        config: SafecaseConfig,
        *,
        params: StoppingParams | None = None,
        writer: AuditWriter | BackgroundAuditWriter | None = None,
    ) -> None:
        self.config = config
        self.governor = Governor(config, params)
        self.tracker = Tracker(config.track)
        self.writer = writer
        g = config.geometry
        self.robot_radius_m = math.hypot(g.footprint_length_m / 2, g.footprint_width_m / 2)
        self.previous_now_s: float | None = None
        self.previous_scan_stamp_s: float | None = None

    def _governor_inputs(self, now_s: float, fused: FusedTracks) -> GovernorInputs:
        t = fused.tracks
        live = t.with_status(*_LIVE)
        radius = np.hypot(t.width_m[live], t.length_m[live]) / 2
        track_d = np.hypot(t.state[live, 0], t.state[live, 1]) - radius
        ped_d = np.hypot(fused.pedestrian_x_m, fused.pedestrian_y_m) - PERSON_RADIUS_M
        distance = np.maximum(np.concatenate([track_d, ped_d]) - self.robot_radius_m, 0.0)
        person = float(self.governor.params.person_speed_mps)
        worst = float(self.governor.params.worst_closing_speed_mps)
        closing = np.concatenate([np.full(track_d.shape, worst), np.full(ped_d.shape, person)])
        confidence = np.concatenate([fused.confidence[live], fused.pedestrian_confidence])
        return GovernorInputs(now_s, distance, closing, confidence, None)

    def step(
        self,
        scan: Scan | None,
        now_s: float,
        *,
        thermal: ThermalDetections | None = None,
        radar: RadarDetections | None = None,
        driver: DriverHealth | None = None,
        delay_s: float = 0.0,
        fault: Callable[[str], None] | None = None,
    ) -> CycleResult:
        """Run one cycle on ``scan`` with decision time ``now_s`` [s] (the wall-clock time the
        stages take is added to it). ``delay_s`` is extra time charged to the cycle (a stalled
        stage); ``fault(stage)`` may raise to simulate a failing stage."""
        wall: dict[str, float] = {}
        stage_verdicts: list[Verdict] = []
        inputs: GovernorInputs | None = None
        parts: dict[str, Any] = {"scan": scan}
        cpu0 = time.thread_time_ns()
        start = time.perf_counter_ns()
        mark = start

        def lap(name: str) -> None:
            nonlocal mark
            now = time.perf_counter_ns()
            wall[name] = (now - mark) * 1e-9
            mark = now

        over_cap: list[tuple[str, int]] = []
        drops = None
        try:
            if scan is None:
                raise ValueError("no scan")
            for stage in ("points", "cluster", "track", "fusion", "governor_inputs"):
                if fault is not None:
                    fault(stage)
                if stage == "points":
                    points = scan_to_points(scan, self.config.scan)
                    drops = points.drops
                elif stage == "cluster":
                    clusters = cluster_points(points, self.config.cluster)
                    parts["clusters"] = clusters.counts
                    over_cap.append(("cluster.max_clusters", clusters.counts.n_over_cap))
                elif stage == "track":
                    tracks = self.tracker.step(Detections.from_clusters(clusters))
                    counts = self.tracker.last_counts
                    parts["tracker"] = counts
                    if counts is not None:
                        over_cap.append(("track.max_detections", counts.n_detections_dropped))
                        over_cap.append(("track.max_tracks", counts.n_births_refused))
                elif stage == "fusion":
                    fuse_now = now_s + (time.perf_counter_ns() - start) * 1e-9
                    fused = fuse(fuse_now, tracks, self.config, thermal=thermal, radar=radar)
                    parts["fusion"] = fused.counts
                    over_cap.append(("fusion.max_thermal", fused.counts.n_thermal_over_cap))
                    over_cap.append(("fusion.max_radar", fused.counts.n_radar_over_cap))
                else:
                    inputs = self._governor_inputs(now_s, fused)
                    excess = inputs.free_distance_m.shape[0] - self.config.geometry.max_obstacles
                    over_cap.append(("geometry.max_obstacles", max(excess, 0)))
                lap(stage)
        except Exception as exc:  # a failing stage stops the robot with the reason
            failed = next(
                s
                for s in ("points", "cluster", "track", "fusion", "governor_inputs")
                if s not in wall
            )
            stage_verdicts.append(Verdict.stop(f"stage:{failed}", f"{type(exc).__name__}: {exc}"))
            inputs = None
            lap(failed)
        duration = (time.perf_counter_ns() - start) * 1e-9 + delay_s
        decision_now = now_s + duration
        observation = Observation(
            now_s=decision_now,
            previous_now_s=self.previous_now_s,
            scan_stamp_s=None if scan is None else scan.stamp_s,
            previous_scan_stamp_s=self.previous_scan_stamp_s,
            scan_complete=True if scan is None else scan.complete,
            n_beams=0 if drops is None else drops.n_beams,
            n_below_min=0 if drops is None else drops.n_below_min,
            driver_state=None if driver is None else driver.state.value,
            driver_age_s=None if driver is None else driver.age_s,
            driver_error="" if driver is None else driver.last_error,
            cycle_duration_s=duration,
            over_cap=tuple(over_cap),
        )
        decision = decide(self.governor, inputs, observation, self.config.monitors, stage_verdicts)
        lap("decide")
        cpu = (time.thread_time_ns() - cpu0) * 1e-9
        self.previous_now_s = max(decision_now, self.previous_now_s or -math.inf)
        if scan is not None:
            self.previous_scan_stamp_s = max(scan.stamp_s, self.previous_scan_stamp_s or -math.inf)
        parts["drops"] = drops
        record = CycleRecord(observation, decision, inputs, summarize(**parts), wall)
        if self.writer is not None:
            self.writer.append(record)
        return CycleResult(decision.command, decision, wall, cpu, record)


def thermal_from_truth(
    truth: ScanTruth,
    rng: np.random.Generator,
    *,
    delay_s: float = 0.0,
    noise_std_m: float = 0.1,
    confidence: float = 0.9,
) -> ThermalDetections:
    """Thermal detections of the simulated persons, in the robot frame at ``truth.stamp_s``.

    Positions get Gaussian noise (``noise_std_m``); every detection is stamped ``delay_s``
    before the scan (a late or stale camera frame).
    """
    person = KIND_NAMES.index(ObjectKind.PERSON.value)
    keep = truth.kind == person
    x, y, yaw = (float(v) for v in truth.ego_pose)
    dx, dy = truth.x_m[keep] - x, truth.y_m[keep] - y
    c, s = math.cos(yaw), math.sin(yaw)
    n = int(np.count_nonzero(keep))
    return ThermalDetections(
        stamp_s=np.full(n, truth.stamp_s - delay_s),
        x_m=c * dx + s * dy + rng.normal(0.0, noise_std_m, n),
        y_m=-s * dx + c * dy + rng.normal(0.0, noise_std_m, n),
        confidence=np.full(n, confidence),
    )
