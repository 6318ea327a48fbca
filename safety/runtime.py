"""One runtime cycle: scan -> ... -> command, timed per stage and audited (SR-RUN-*, SR-AUD-*).

The whole chain (docs/architecture.md) runs once per scan: the perception chain
(:class:`pipeline.perception.Perception`: filter, clusters, shapes, tracks in the tracking frame
placed by the robot's odometry pose at the scan's stamp, features, classes, fusion with the
freshness guard of :mod:`safety.model.freshness`, predictions), then the safety side:
envelopes, the free distance along the robot's path to every predicted zone
(:mod:`safety.geometry.path`), the planner's swept-path check and the costmap (recorded for a
planner), and :func:`safety.model.decision.decide`: the governor, the monitors and the stage
verdicts folded into one command.

What the governor is given, per cycle:

- one row per prediction row: the free distance along the path to the predicted zone (the
  reach region grown by the body, no margin: the governor applies the margin tier), the
  envelope's closing speed (for moving objects other than people, direction-aware: the
  largest component along the path towards the robot of any velocity their cone allows,
  :mod:`safety.closing`, SR-AVL-5), confidence and near-reversal flag;
- one row per thermal-only pedestrian: a disc of ``runtime.person_radius_m`` grown by the
  walking speed over the horizon and the detection's age, closing at the person speed, with
  the pedestrian's (low) confidence;
- the nearest scan point outside every kept cluster that lies on the path (walls longer than
  the cluster filter, objects with too few returns), as configured by ``runtime.loose_points``;
- the end of the known path (the lookahead, or the end of the route), closing at the fastest
  class's speed with unknown confidence: nothing is assumed about what lies beyond.

A microphone array's alert (a bearing, never a position) adds no row: while it is fresh the
cautious mode caps the command's speed (:mod:`safety.model.caution`, SR-ACU-3), recorded as the
``acoustic_caution`` verdict and the ``acoustic`` input of the cycle's record.

Any stage that raises ends the perception part of the cycle: the decision is then a STOP
naming the stage and the error (the runtime loop itself never raises). The record written to
the audit log holds what :func:`safety.audit.replay.replay` needs to recompute the command.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.frames import to_parent
from pipeline.perception import STAGES as PERCEPTION_STAGES
from pipeline.perception import (
    Partial,
    Perceived,
    Perception,
    PerceptionChain,
    StageError,
    Stopwatch,
)
from pipeline.static_map import StaticMap, map_from_config
from pipeline.types import (
    Action,
    BoolArray,
    Command,
    PredictionMode,
)
from safety.audit.log import AuditWriter, BackgroundAuditWriter, CycleRecord, summarize
from safety.bodies import (
    OnMapMemory,
    SeenHulls,
    StillHulls,
    hull_bodies,
    mapped_rows,
    mapped_zones,
    still_zones,
    tracks_on_map,
)
from safety.closing import directed_closing
from safety.cycle import (
    CycleDetail,
    CycleInput,
    CycleInputError,
    CycleOutput,
    Levers,
    SafetySide,
    alert_part,
    fold_parts,
)
from safety.geometry.costmap import CostmapBuilder
from safety.geometry.envelopes import EnvelopeBuilder
from safety.geometry.path import PathClearance
from safety.geometry.swept import SweptPathChecker
from safety.model.braking import BrakingWatch
from safety.model.caution import caution_verdict
from safety.model.decision import GovernorInputs, decide
from safety.model.freshness import is_fresh
from safety.model.governor import Governor
from safety.model.monitors import MonitorVerdict, Observation
from safety.model.second_scanner import second_scanner_verdict
from safety.model.stopping import StoppingParams
from safety.obstacles import (
    bodies_now,
    faster_than_the_domain,
    governor_rows,
    pedestrian_regions,
    stack_polygons,
)

# The cycle's data types live in safety.cycle; they are re-exported here, where users look.
__all__ = [
    "STAGES",
    "CycleDetail",
    "CycleInput",
    "CycleInputError",
    "CycleOutput",
    "Levers",
    "Runtime",
]

# The perception chain's stages, then the safety side's (the decision is timed as "decide").
STAGES = (*PERCEPTION_STAGES, "envelopes", "path", "planner", "costmap")


class Runtime:
    """The cycle loop's state for one configuration: the perception chain, the safety stages'
    builders and checkers, the audit writer.

    ``params`` overrides the stopping parameters (a measured latency bound); ``classifier``
    defaults to the configured model (hash-checked); ``writer`` receives one record per cycle.
    ``perception`` replaces the configured chain (the ground truth of
    :class:`pipeline.oracle.GroundTruthPerception`: the availability oracle, SR-AVL-1); the
    safety side, the governor and the monitors stay the same. ``levers`` switches the
    availability levers (all on by default; off only to measure what each one buys).
    ``static_map`` is the site's map (default: ``map.file``'s, none when it is empty; a
    simulated run passes its world's, :func:`safety.run.site_map`).
    """

    def __init__(
        self,
        config: SafecaseConfig,
        *,
        params: StoppingParams | None = None,
        classifier: Classifier | None = None,
        writer: AuditWriter | BackgroundAuditWriter | None = None,
        perception: PerceptionChain | None = None,
        levers: Levers | None = None,
        static_map: StaticMap | None = None,
    ) -> None:
        self.config = config
        self.static_map = static_map if static_map is not None else map_from_config(config)
        self.levers = levers if levers is not None else Levers()
        self.params = params if params is not None else StoppingParams.from_config(config)
        self.classifier = (
            classifier if classifier is not None else Classifier.from_config(config.classify)
        )
        self.governor = Governor(config.governor, self.params)
        self.perception: PerceptionChain = (
            perception
            if perception is not None
            else Perception.from_config(config, classifier=self.classifier, guard=is_fresh)
        )
        self.envelopes = EnvelopeBuilder(config.predict, self.params)
        self.clearance = PathClearance(config.geometry)
        self.planner = SweptPathChecker(config.geometry)
        self.costmap = CostmapBuilder(config.costmap)
        self.still_hulls = StillHulls(config.track.dormant_after_misses)
        self.on_map_memory = OnMapMemory()
        self.writer = writer
        self.previous_now_s: float | None = None
        # When the STOP in force was decided (None while moving) and the braking it buys.
        self.stop_since_s: float | None = None
        self.braking = BrakingWatch(config.stopping.control_cycle_s, self.params.decel_max_mps2)
        self.previous_scan_stamp_s: float | None = None
        self.cycles = 0

    def step(self, inp: CycleInput) -> CycleOutput:
        """Run one cycle (never raises; a failing stage gives STOP with its error)."""
        config = self.config
        watch = Stopwatch(on_enter=inp.fault)
        stage_verdicts: list[MonitorVerdict] = []
        cpu0 = time.thread_time_ns()
        start = time.perf_counter_ns()

        def elapsed_s() -> float:
            if inp.charge_s is not None:
                return inp.charge_s
            return (time.perf_counter_ns() - start) * 1e-9

        inputs: GovernorInputs | None = None
        parts: dict[str, Any] = {"scan": inp.scan}
        over_cap: list[tuple[str, int]] = []
        partial = Partial()
        safety_side: SafetySide | None = None
        perceived: Perceived | None = None
        try:
            perceived = self.perception.perceive(
                inp.frame(), now_s=lambda: inp.now_s + elapsed_s(), watch=watch
            )
            partial = Partial(
                perceived.points, perceived.clusters, perceived.tracked.counts, perceived.fused
            )
            on_map = self._on_map(perceived)
            tracks = perceived.fused.tracks
            seen_on_map = self.on_map_memory.update(tracks.track_id, tracks.detection_index, on_map)
            too_fast = faster_than_the_domain(tracks, self.config.predict, seen_on_map)
            if too_fast is not None:
                stage_verdicts.append(too_fast)
            safety_side = self._safety_side(inp, perceived, on_map, elapsed_s, watch)
            inputs = safety_side.inputs
        except StageError as exc:  # a failing stage stops the robot with the reason
            stage_verdicts.append(MonitorVerdict.stop(f"stage:{exc.stage}", str(exc)))
            partial = exc.partial
        except Exception as exc:
            stage_verdicts.append(
                MonitorVerdict.stop(f"stage:{watch.current}", f"{type(exc).__name__}: {exc}")
            )
        fold_parts(parts, over_cap, partial, safety_side)
        with watch.stage("decide"):
            duration = elapsed_s() + inp.delay_s
            decision_now = inp.now_s + duration
            drops = partial.points.drops if partial.points is not None else None
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
                braking_decel_mps2=self.braking.observe(
                    None if inp.scan is None else inp.scan.stamp_s,
                    inp.robot_pose,
                    self.stop_since_s,
                ),
                braking_min_mps2=float(self.params.decel_min_mps2),
            )
            if inp.acoustic is not None:
                # A fresh alert caps the speed (SR-ACU-3); recorded as a verdict and an input.
                caution = caution_verdict(
                    decision_now, inp.acoustic, self.config.acoustic, self.governor.max_speed_mps
                )
                stage_verdicts.append(caution)
                parts["acoustic"] = alert_part(inp.acoustic, caution)
            second = None if perceived is None else perceived.tracked.second
            if second is not None:
                # A second scanner's points count only while fresh at decision time (SR-LID-2).
                stage_verdicts.append(
                    second_scanner_verdict(second, decision_now, config.scan2, config.monitors)
                )
                parts["second_scan"] = second
            decision = decide(self.governor, inputs, observation, config.monitors, stage_verdicts)
        cpu = (time.thread_time_ns() - cpu0) * 1e-9
        self.previous_now_s = max(decision_now, self.previous_now_s or -math.inf)
        if inp.scan is not None:
            stamp = inp.scan.stamp_s
            if math.isfinite(stamp):
                self.previous_scan_stamp_s = max(stamp, self.previous_scan_stamp_s or -math.inf)
        wall = dict(watch.wall_s)
        record = CycleRecord(observation, decision, inputs, summarize(**parts), wall)
        command = decision.command
        if command.action is not Action.STOP:
            self.stop_since_s = None
        elif self.stop_since_s is None:
            self.stop_since_s = decision_now
        if self.writer is not None:
            try:
                self.writer.append(record)
            except Exception as exc:  # a decision that cannot be recorded is not acted on
                why = f"audit: the cycle could not be recorded ({type(exc).__name__}: {exc})"
                command = Command(Action.STOP, 0.0, command.stamp_s, (why,))
        self.cycles += 1
        return CycleOutput(
            command,
            decision,
            record,
            wall,
            cpu,
            None if safety_side is None else safety_side.envelopes,
            None if safety_side is None else safety_side.distances,
            CycleDetail(inp, perceived, None if safety_side is None else safety_side.grid),
        )

    def _on_map(self, perceived: Perceived) -> BoolArray:
        """Per track: updated by a cluster lying wholly on the site's map (none without a map
        or with the lever off; SR-AVL-8)."""
        tracks = perceived.fused.tracks
        if not self.levers.mapped_structure or self.static_map is None:
            return np.zeros(tracks.track_id.shape, dtype=bool)
        return tracks_on_map(
            tracks, perceived.clusters, perceived.points, perceived.pose, self.static_map
        )

    def _safety_side(
        self,
        inp: CycleInput,
        perceived: Perceived,
        on_map: BoolArray,
        elapsed_s: Callable[[], float],
        watch: Stopwatch,
    ) -> SafetySide:
        """Envelopes, path clearance, the planner's check and the costmap: the governor's
        inputs from what perception saw (module docstring)."""
        config = self.config
        pred, fused, pose = perceived.predictions, perceived.fused, perceived.pose
        clusters, points = perceived.clusters, perceived.points
        with watch.stage("envelopes"):
            names = perceived.classification.class_names
            robot_now = (
                float(inp.path.x_m[0]),
                float(inp.path.y_m[0]),
                float(inp.path.theta_rad[0]),
            )
            env = self.envelopes.build(pred, names, robot_pose=robot_now)
            ped_zones, ped_env = pedestrian_regions(
                inp.now_s + elapsed_s(), fused, robot_now, config, self.params, self.envelopes
            )
        with watch.stage("path"):
            unknown = pred.mode == int(PredictionMode.UNKNOWN)
            still = pred.mode == int(PredictionMode.FOOTPRINT)
            seen = SeenHulls.of(still | unknown, pred, fused.tracks, clusters, pose, config.predict)
            zones = still_zones(pred, seen, config.predict)
            if self.levers.outline_bodies:
                # A still object not seen this cycle keeps its last hull (SR-AVL-6).
                zones = self.still_hulls.zones(
                    zones, pred, fused.tracks, clusters, pose, config.predict
                )
            # Unknown motion wholly on the site's map is the fixed structure: it is where it
            # stands, so its hull is a zone read along the path (SR-AVL-8).
            mapped = mapped_rows(unknown, pred, fused.tracks, on_map)
            zones = mapped_zones(zones, mapped, pred, fused.tracks, seen, config.predict.disc_sides)
            loose = clusters.point_labels < 0
            dist = self.clearance.free_distances(
                inp.path, zones, *to_parent(pose, points.x_m[loose], points.y_m[loose])
            )
            here = bodies_now(pred, fused.tracks, unknown, config.predict.disc_sides)
            if self.levers.outline_bodies:
                # An object of unknown motion seen this cycle is its cluster's hull (SR-AVL-6).
                here = hull_bodies(unknown, here, seen)
            free = dist.zone_free_m.copy()
            free[unknown] = self.clearance.distances_now(inp.path, here)
            free[mapped] = dist.zone_free_m[mapped]
            ped_free = self.clearance.distances_now(inp.path, ped_zones)
            path_part = {
                "lookahead_m": dist.lookahead_m,
                "zones_on_path": int(np.count_nonzero(dist.zone_hit)),
                "nearest_zone_m": float(dist.zone_free_m.min(initial=dist.lookahead_m)),
                "loose_points_on_path": dist.n_points_on_path,
                "nearest_loose_point_m": dist.point_free_m,
                "nearest_unknown_m": float(free[unknown].min(initial=dist.lookahead_m)),
                "unknown_on_map": int(np.count_nonzero(mapped)),
                "nearest_pedestrian_m": float(ped_free.min(initial=dist.lookahead_m)),
            }
            all_env = stack_polygons(env.polygons, ped_env)
            excess = max(all_env.n - config.geometry.max_obstacles, 0)
        planner_part = costmap_part = grid = None
        with watch.stage("planner"):
            if config.runtime.planner_check and not excess:
                report = self.planner.check(
                    self.planner.footprint(),
                    self.planner.candidates(self.params.robot_max_speed_mps),
                    all_env,
                )
                planner_part = {
                    "candidates": int(report.blocked.shape[0]),
                    "blocked": int(np.count_nonzero(report.blocked.any(axis=1))),
                }
        with watch.stage("costmap"):
            if config.runtime.costmap:
                grid = self.costmap.rasterize(all_env)
                costmap_part = {
                    "occupied_cells": int(np.count_nonzero(grid.occupied)),
                    "clipped": grid.n_clipped,
                }
        if self.levers.directed_closing:
            # Moving objects close in at most at their speed's component along the path
            # (SR-AVL-5).
            closing = directed_closing(env, pred, fused.tracks, names, inp.path, free, self.params)
            env = replace(env, closing_speed_mps=closing)
        inputs = governor_rows(
            inp.now_s, env, fused, free, ped_free, dist, self.params, config.runtime.loose_points
        )
        return SafetySide(inputs, env, dist, excess, path_part, planner_part, costmap_part, grid)
