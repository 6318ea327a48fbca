"""What one runtime cycle reads and gives back (SR-RUN-*): its input, its output and the
detail a recording keeps, the availability levers a runtime is built with, what its safety
stages produced and the summary parts of its audit record. The cycle itself is
:class:`safety.runtime.Runtime`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pipeline.config import SafecaseConfig
from pipeline.errors import SafecaseError
from pipeline.frames import Pose
from pipeline.perception import Partial, Perceived
from pipeline.types import (
    Action,
    Command,
    DriverHealth,
    Envelopes,
    Frame,
    RadarDetections,
    Scan,
    SecondScan,
    ThermalDetections,
)
from pipeline.types.acoustic import AcousticAlert
from pipeline.types.sensors import Twist
from safety.audit.log import CycleRecord
from safety.geometry.costmap import Costmap
from safety.geometry.path import PathAhead, PathDistances
from safety.model.decision import Decision, GovernorInputs
from safety.model.monitors import MonitorVerdict

__all__ = [
    "CycleDetail",
    "CycleInput",
    "CycleInputError",
    "CycleOutput",
    "Levers",
    "SafetySide",
    "alert_part",
    "fold_parts",
]


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
    measured times are still recorded). ``acoustic`` is the microphone array's newest alert,
    which caps the speed while fresh (SR-ACU-3). ``second`` is a second scanner's newest
    revolution (SR-LID-1). ``twist`` is the robot's velocity at the scan's stamp (odometry,
    robot frame), needed to use radar returns while the robot moves (SR-FUS-9).
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
    acoustic: AcousticAlert | None = None
    second: SecondScan | None = None
    twist: Twist | None = None

    @classmethod
    def standing(
        cls, scan: Scan | None, now_s: float, config: SafecaseConfig, **extra: Any
    ) -> CycleInput:
        """A cycle of a robot that does not move (tracking in the robot frame, the path
        straight ahead), as on a test bench or with a scanner read without odometry."""
        rc = config.runtime
        path = PathAhead.straight((0.0, 0.0, 0.0), rc.path_lookahead_m, rc.path_step_m)
        return cls(scan=scan, now_s=now_s, robot_pose=(0.0, 0.0, 0.0), path=path, **extra)

    def frame(self) -> Frame:
        """What the perception chain reads of this input (the link's health and the acoustic
        alert are not among it: the runtime reads ``driver`` and ``acoustic`` directly)."""
        return Frame(
            self.scan,
            self.now_s,
            pose=self.robot_pose,
            thermal=self.thermal,
            radar=self.radar,
            second=self.second,
            twist=self.twist,
        )


@dataclass(frozen=True, slots=True)
class CycleDetail:
    """What a cycle read and built, for a recording of the run (:mod:`safety.foxglove`): its
    input, the perception chain's result and the costmap (each None when the cycle stopped
    before it, or the costmap is off)."""

    inp: CycleInput
    perceived: Perceived | None
    costmap: Costmap | None


@dataclass(frozen=True, slots=True)
class CycleOutput:
    """One cycle's result: the command, the decision, what was logged, per-stage wall-clock
    times and the thread's CPU time [s], the envelopes (robot frame; None when the cycle
    stopped before them), the path distances and the cycle's :class:`CycleDetail`."""

    command: Command
    decision: Decision
    record: CycleRecord
    wall_s: dict[str, float]
    cpu_s: float
    envelopes: Envelopes | None
    distances: PathDistances | None
    detail: CycleDetail | None = None


@dataclass(frozen=True)
class Levers:
    """The availability levers (SR-AVL-5, SR-AVL-6, SR-AVL-8), each proved or argued not to
    weaken a safety obligation: ``directed_closing`` (:mod:`safety.closing`), ``outline_bodies``
    and ``mapped_structure`` (:mod:`safety.bodies`; it acts only where the runtime has a site
    map)."""

    directed_closing: bool = True
    outline_bodies: bool = True
    mapped_structure: bool = True


@dataclass(frozen=True)
class SafetySide:
    """What the safety stages of one cycle produced, for the decision and the record (the
    path, planner and costmap parts are the record's summaries)."""

    inputs: GovernorInputs
    envelopes: Envelopes
    distances: PathDistances
    excess_obstacles: int
    path: dict[str, Any]
    planner: dict[str, Any] | None
    costmap: dict[str, Any] | None
    grid: Costmap | None


def alert_part(alert: object, caution: MonitorVerdict) -> dict[str, Any]:
    """The audit record's summary of an acoustic alert and whether it capped the speed (an
    input that is not an alert is named, never read: its verdict is already a STOP)."""
    if not isinstance(alert, AcousticAlert):
        return {"invalid": type(alert).__name__, "caution": True}
    return {
        "kind": alert.kind.value,
        "bearing_rad": alert.bearing_rad,
        "confidence": alert.confidence,
        "stamp_s": alert.stamp_s,
        "caution": caution.action is not Action.PROCEED,
    }


def fold_parts(
    parts: dict[str, Any],
    over_cap: list[tuple[str, int]],
    partial: Partial,
    side: SafetySide | None,
) -> None:
    """The audit record's summary parts and the over-cap counts, from what the cycle reached."""
    if partial.points is not None:
        parts["drops"] = partial.points.drops
    if partial.clusters is not None:
        parts["clusters"] = partial.clusters.counts
        over_cap.append(("cluster.max_clusters", partial.clusters.counts.n_over_cap))
    if partial.counts is not None:
        parts["tracker"] = partial.counts
        over_cap.append(("track.max_detections", partial.counts.n_detections_dropped))
        over_cap.append(("track.max_tracks", partial.counts.n_births_refused))
    if partial.fused is not None:
        parts["fusion"] = partial.fused.counts
        over_cap.append(("fusion.max_thermal", partial.fused.counts.n_thermal_over_cap))
        over_cap.append(("fusion.max_radar", partial.fused.counts.n_radar_over_cap))
    if side is not None:
        parts["path"] = side.path
        over_cap.append(("geometry.max_obstacles", side.excess_obstacles))
        if side.planner is not None:
            parts["planner"] = side.planner
        if side.costmap is not None:
            parts["costmap"] = side.costmap
