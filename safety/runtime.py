"""One runtime cycle: scan -> ... -> command, timed per stage and audited (SR-RUN-*, SR-AUD-*).

The whole chain of DESIGN.md runs once per scan: sanitation, clustering, tracking (in the
tracking frame, with the robot's odometry pose at the scan's stamp), features, classification,
fusion (thermal detections moved into the tracking frame), prediction, envelopes, the free
distance along the robot's path to every predicted zone (:mod:`safety.path`), the planner's
swept-path check and the costmap (recorded for a planner), then :func:`safety.decision.decide`:
the governor, the monitors and the stage verdicts folded into one command.

What the governor is given, per cycle:

- one row per prediction row: the free distance along the path to the predicted zone (the
  reach region grown by the body, no margin: the governor applies the margin tier), the
  envelope's closing speed, confidence and near-reversal flag;
- one row per thermal-only pedestrian: a disc of ``runtime.person_radius_m`` grown by the
  walking speed over the horizon and the detection's age, closing at the person speed, with
  the pedestrian's (low) confidence;
- the nearest scan point outside every kept cluster that lies on the path (walls longer than
  the cluster filter, objects with too few returns), as configured by ``runtime.loose_points``;
- the end of the known path (the lookahead, or the end of the route), closing at the fastest
  class's speed with unknown confidence: nothing is assumed about what lies beyond.

Any stage that raises ends the perception part of the cycle: the decision is then a STOP
naming the stage and the error (the runtime loop itself never raises). The record written to
the audit log holds what :func:`safety.replay.replay` needs to recompute the command.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from pipeline.classify import Classifier
from pipeline.cluster import cluster_points
from pipeline.config import SafecaseConfig
from pipeline.errors import SafecaseError
from pipeline.features import detections_in_frame, track_features
from pipeline.fusion import fuse
from pipeline.points import scan_to_points
from pipeline.predict import predict
from pipeline.track.tracker import Tracker
from pipeline.types import (
    Action,
    Command,
    DriverHealth,
    Envelopes,
    PredictionMode,
    RadarDetections,
    Scan,
    ThermalDetections,
)
from safety.audit import AuditWriter, BackgroundAuditWriter, CycleRecord, summarize
from safety.costmap import CostmapBuilder
from safety.decision import Decision, GovernorInputs, decide
from safety.envelope import EnvelopeBuilder
from safety.governor import Governor
from safety.monitors import Observation, Verdict
from safety.obstacles import (
    bodies_now,
    faster_than_the_domain,
    governor_rows,
    pedestrian_regions,
    points_in_frame,
    stack_polygons,
    still_zones,
    thermal_in_frame,
)
from safety.path import PathAhead, PathClearance, PathDistances
from safety.stopping import StoppingParams
from safety.swept import SweptPathChecker

__all__ = ["STAGES", "CycleInput", "CycleInputError", "CycleOutput", "Runtime"]

STAGES = (
    "points",
    "cluster",
    "track",
    "features",
    "classify",
    "fusion",
    "predict",
    "envelopes",
    "path",
    "planner",
    "costmap",
)

Pose = tuple[float, float, float]


class CycleInputError(SafecaseError, ValueError):
    """A cycle input that cannot be processed (raised inside a stage, recorded as its STOP)."""


@dataclass(frozen=True, slots=True)
class CycleInput:
    """Everything one cycle reads.

    ``now_s`` is the decision clock when the scan became available [s]; ``robot_pose`` the
    robot's (x_m, y_m, yaw_rad) in the tracking frame at the scan's stamp (odometry; the
    identity for a robot that does not move, e.g. on a test bench); ``path`` the robot's path
    ahead from its current pose, in the tracking frame. ``thermal`` and ``radar`` are in the
    robot frame at ``robot_pose``. ``delay_s`` is extra time charged to the cycle (a stalled
    stage, in tests); ``fault(stage)`` may raise to make a stage fail (tests). ``charge_s``, when
    given, is the cycle's duration on the decision clock in place of the measured one (a
    simulated clock: the closed loop then does not depend on this machine's speed and load; the
    measured times are still recorded).
    """

    scan: Scan | None
    now_s: float
    robot_pose: Pose
    path: PathAhead
    thermal: ThermalDetections | None = None
    radar: RadarDetections | None = None
    driver: DriverHealth | None = None
    delay_s: float = 0.0
    fault: Callable[[str], None] | None = None
    charge_s: float | None = None

    @classmethod
    def standing(
        cls, scan: Scan | None, now_s: float, config: SafecaseConfig, **extra: Any
    ) -> CycleInput:
        """A cycle of a robot that does not move (tracking in the robot frame, the path
        straight ahead), as on a test bench or with a scanner read without odometry."""
        rc = config.runtime
        path = PathAhead.straight((0.0, 0.0, 0.0), rc.path_lookahead_m, rc.path_step_m)
        return cls(scan=scan, now_s=now_s, robot_pose=(0.0, 0.0, 0.0), path=path, **extra)


@dataclass(frozen=True, slots=True)
class CycleOutput:
    """One cycle's result: the command, the decision, what was logged, per-stage wall-clock
    times and the thread's CPU time [s], the envelopes (robot frame; None when the cycle
    stopped before them) and the path distances."""

    command: Command
    decision: Decision
    record: CycleRecord
    wall_s: dict[str, float]
    cpu_s: float
    envelopes: Envelopes | None
    distances: PathDistances | None


class Runtime:
    """The cycle loop's state for one configuration: tracker, classifier, checkers, writer.

    ``params`` overrides the stopping parameters (a measured latency bound); ``classifier``
    defaults to the configured model (hash-checked); ``writer`` receives one record per cycle.
    """

    def __init__(
        self,
        config: SafecaseConfig,
        *,
        params: StoppingParams | None = None,
        classifier: Classifier | None = None,
        writer: AuditWriter | BackgroundAuditWriter | None = None,
    ) -> None:
        self.config = config
        self.params = params if params is not None else StoppingParams.from_config(config)
        self.classifier = (
            classifier if classifier is not None else Classifier.from_config(config.classify)
        )
        self.governor = Governor(config, self.params)
        self.tracker = Tracker(config.track)
        self.envelopes = EnvelopeBuilder(config, self.params)
        self.clearance = PathClearance(config.geometry)
        self.planner = SweptPathChecker(config.geometry)
        self.costmap = CostmapBuilder(config.costmap)
        self.writer = writer
        self.previous_now_s: float | None = None
        self.previous_scan_stamp_s: float | None = None
        self.cycles = 0

    def step(self, inp: CycleInput) -> CycleOutput:
        """Run one cycle (never raises; a failing stage gives STOP with its error)."""
        wall: dict[str, float] = {}
        parts: dict[str, Any] = {"scan": inp.scan}
        over_cap: list[tuple[str, int]] = []
        stage_verdicts: list[Verdict] = []
        state: dict[str, Any] = {
            "stage": STAGES[0],
            "envelopes": None,
            "distances": None,
            "verdicts": stage_verdicts,
        }
        cpu0 = time.thread_time_ns()
        start = time.perf_counter_ns()
        clock = [start]

        def enter(name: str) -> None:
            now = time.perf_counter_ns()
            wall[state["stage"]] = (now - clock[0]) * 1e-9
            clock[0] = now
            state["stage"] = name
            if inp.fault is not None:
                inp.fault(name)

        def elapsed_s() -> float:
            if inp.charge_s is not None:
                return inp.charge_s
            return (time.perf_counter_ns() - start) * 1e-9

        inputs: GovernorInputs | None = None
        try:
            if inp.fault is not None:
                inp.fault(STAGES[0])
            inputs = self._perceive(inp, enter, elapsed_s, parts, over_cap, state)
            enter("decide")
        except Exception as exc:  # a failing stage stops the robot with the reason
            failed = state["stage"]
            stage_verdicts.append(Verdict.stop(f"stage:{failed}", f"{type(exc).__name__}: {exc}"))
            inputs = None
            enter("decide")
        duration = elapsed_s() + inp.delay_s
        decision_now = inp.now_s + duration
        drops = parts.get("drops")
        observation = Observation(
            now_s=decision_now,
            previous_now_s=self.previous_now_s,
            scan_stamp_s=None if inp.scan is None else inp.scan.stamp_s,
            previous_scan_stamp_s=self.previous_scan_stamp_s,
            scan_complete=True if inp.scan is None else inp.scan.complete,
            n_beams=0 if drops is None else drops.n_beams,
            n_below_min=0 if drops is None else drops.n_below_min,
            driver_state=None if inp.driver is None else inp.driver.state.value,
            driver_age_s=None if inp.driver is None else inp.driver.age_s,
            driver_error="" if inp.driver is None else inp.driver.last_error,
            cycle_duration_s=duration,
            over_cap=tuple(over_cap),
        )
        decision = decide(self.governor, inputs, observation, self.config.monitors, stage_verdicts)
        now = time.perf_counter_ns()
        wall["decide"] = (now - clock[0]) * 1e-9
        cpu = (time.thread_time_ns() - cpu0) * 1e-9
        self.previous_now_s = max(decision_now, self.previous_now_s or -math.inf)
        if inp.scan is not None:
            stamp = inp.scan.stamp_s
            if math.isfinite(stamp):
                self.previous_scan_stamp_s = max(stamp, self.previous_scan_stamp_s or -math.inf)
        record = CycleRecord(observation, decision, inputs, summarize(**parts), wall)
        command = decision.command
        if self.writer is not None:
            try:
                self.writer.append(record)
            except Exception as exc:  # a decision that cannot be recorded is not acted on
                why = f"audit: the cycle could not be recorded ({type(exc).__name__}: {exc})"
                command = Command(Action.STOP, 0.0, command.stamp_s, (why,))
        self.cycles += 1
        return CycleOutput(
            command, decision, record, wall, cpu, state["envelopes"], state["distances"]
        )

    def _perceive(
        self,
        inp: CycleInput,
        enter: Callable[[str], None],
        elapsed_s: Callable[[], float],
        parts: dict[str, Any],
        over_cap: list[tuple[str, int]],
        state: dict[str, Any],
    ) -> GovernorInputs:
        """The perception stages up to the governor's inputs (module docstring)."""
        config = self.config
        if inp.scan is None:
            raise CycleInputError("no scan this cycle")
        pose = tuple(float(v) for v in inp.robot_pose)
        if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
            raise CycleInputError(f"robot_pose {inp.robot_pose!r}: expected finite (x_m, y_m, yaw)")
        points = scan_to_points(inp.scan, config.scan)
        parts["drops"] = points.drops
        enter("cluster")
        clusters = cluster_points(points, config.cluster)
        parts["clusters"] = clusters.counts
        over_cap.append(("cluster.max_clusters", clusters.counts.n_over_cap))
        enter("track")
        tracks = self.tracker.step(detections_in_frame(clusters, (pose[0], pose[1], pose[2])))
        counts = self.tracker.last_counts
        parts["tracker"] = counts
        if counts is not None:
            over_cap.append(("track.max_detections", counts.n_detections_dropped))
            over_cap.append(("track.max_tracks", counts.n_births_refused))
        enter("features")
        features = track_features(tracks, clusters, config.predict, (pose[0], pose[1]))
        enter("classify")
        classification = self.classifier.classify(features)
        enter("fusion")
        if inp.radar is not None and pose != (0.0, 0.0, 0.0):
            raise CycleInputError(
                "radar fusion needs the tracking frame to be the robot frame (no ego-motion "
                "compensation of Doppler yet); got a moving robot_pose"
            )
        thermal = None if inp.thermal is None else thermal_in_frame(inp.thermal, pose)
        fused = fuse(
            inp.now_s + elapsed_s(),
            tracks,
            config,
            confidence=classification.confidence,
            thermal=thermal,
            radar=inp.radar,
        )
        parts["fusion"] = fused.counts
        over_cap.append(("fusion.max_thermal", fused.counts.n_thermal_over_cap))
        over_cap.append(("fusion.max_radar", fused.counts.n_radar_over_cap))
        enter("predict")
        boosted = replace(classification, confidence=fused.confidence)
        pred = predict(fused.tracks, features, boosted, config)
        too_fast = faster_than_the_domain(fused.tracks, config.predict)
        if too_fast is not None:
            state["verdicts"].append(too_fast)
        enter("envelopes")
        names = self.classifier.class_names
        robot_now = (float(inp.path.x_m[0]), float(inp.path.y_m[0]), float(inp.path.theta_rad[0]))
        env = self.envelopes.build(pred, names, robot_pose=robot_now)
        ped_zones, ped_env = pedestrian_regions(
            inp.now_s + elapsed_s(), fused, robot_now, config, self.params, self.envelopes
        )
        state["envelopes"] = env
        enter("path")
        zones = still_zones(pred, fused.tracks, clusters, pose, config.predict)
        loose = clusters.point_labels < 0
        dist = self.clearance.free_distances(
            inp.path, zones, *points_in_frame(points.x_m[loose], points.y_m[loose], pose)
        )
        unknown = pred.mode == int(PredictionMode.UNKNOWN)
        here = bodies_now(pred, fused.tracks, unknown, config.predict.disc_sides)
        free = dist.zone_free_m.copy()
        free[unknown] = self.clearance.distances_now(inp.path, here)
        ped_free = self.clearance.distances_now(inp.path, ped_zones)
        state["distances"] = dist
        parts["path"] = {
            "lookahead_m": dist.lookahead_m,
            "zones_on_path": int(np.count_nonzero(dist.zone_hit)),
            "nearest_zone_m": float(dist.zone_free_m.min(initial=dist.lookahead_m)),
            "loose_points_on_path": dist.n_points_on_path,
            "nearest_loose_point_m": dist.point_free_m,
            "nearest_unknown_m": float(free[unknown].min(initial=dist.lookahead_m)),
            "nearest_pedestrian_m": float(ped_free.min(initial=dist.lookahead_m)),
        }
        all_env = stack_polygons(env.polygons, ped_env)
        excess = max(all_env.n - config.geometry.max_obstacles, 0)
        over_cap.append(("geometry.max_obstacles", excess))
        enter("planner")
        if config.runtime.planner_check and not excess:
            report = self.planner.check(
                self.planner.footprint(),
                self.planner.candidates(self.params.robot_max_speed_mps),
                all_env,
            )
            parts["planner"] = {
                "candidates": int(report.blocked.shape[0]),
                "blocked": int(np.count_nonzero(report.blocked.any(axis=1))),
            }
        enter("costmap")
        if config.runtime.costmap:
            grid = self.costmap.rasterize(all_env)
            parts["costmap"] = {
                "occupied_cells": int(np.count_nonzero(grid.occupied)),
                "clipped": grid.n_clipped,
            }
        return governor_rows(
            inp.now_s, env, fused, free, ped_free, dist, self.params, config.runtime.loose_points
        )
