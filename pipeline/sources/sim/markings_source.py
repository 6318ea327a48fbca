"""The marking localisation run beside a simulated source, never inside it (SR-MRK-3, SR-MRK-4).

:class:`MarkingsSource` wraps a closed-loop :class:`~pipeline.sources.sim.source.SimSource`:
it yields the inner source's frames unchanged, object for object, and for each scan renders a
ring scan at the robot's true pose (:func:`~pipeline.sources.sim.rings.ring_scan`, from its own
generator, so the simulator's streams are untouched), detects the markings, dead-reckons an
odometry estimate drifting by :class:`Drift` and corrects it by map matching
(:class:`~pipeline.sensors.localisation.Localiser`). What it found is kept in
:attr:`MarkingsSource.reports` for a localisation consumer and for the run's report; the frame
the runtime decides on does not carry it, so the safety chain cannot depend on it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from pipeline.config import MarkingsSection, SafecaseConfig
from pipeline.sensors.localisation import Localiser, PoseCorrection, compose, relative
from pipeline.sensors.marking_map import MarkingMap
from pipeline.sensors.markings import detect_markings
from pipeline.sources.sim.apron_markings import apron_markings
from pipeline.sources.sim.rings import Surface, ring_scan
from pipeline.sources.sim.simulation import Simulation
from pipeline.sources.sim.source import SimSource, SimSourceBeside
from pipeline.types import Frame, Pose

__all__ = ["Drift", "MarkingReport", "MarkingsSource", "markings_beside"]


@dataclass(frozen=True, slots=True)
class Drift:
    """Odometry error: travelled distance scaled by ``1 + scale_error`` and a constant yaw-rate
    bias ``yaw_bias_rps`` [rad/s] (wheel radius and gyro bias, the classic drifts)."""

    scale_error: float = 0.02
    yaw_bias_rps: float = 0.002

    def increment(self, true_delta: Pose, dt_s: float) -> Pose:
        """The odometry's reading of a true increment over ``dt_s`` [s]."""
        k = 1.0 + self.scale_error
        return (k * true_delta[0], k * true_delta[1], true_delta[2] + self.yaw_bias_rps * dt_s)


@dataclass(frozen=True, slots=True)
class MarkingReport:
    """One scan's localisation aid: the true pose (the simulator's), the odometry-only
    estimate, the corrected estimate and the correction, with the markings found."""

    stamp_s: float
    true_pose: Pose
    odometry_pose: Pose
    corrected_pose: Pose
    correction: PoseCorrection
    n_lines: int
    n_arcs: int

    @staticmethod
    def error_m(estimate: Pose, truth: Pose) -> float:
        """Position error of an estimate [m]."""
        return math.hypot(estimate[0] - truth[0], estimate[1] - truth[1])


class MarkingsSource(SimSourceBeside):
    """``inner``'s frames, unchanged, with the marking localisation beside them (module
    docstring). ``rng`` draws the ring scans' noise; ``drift`` the odometry's error."""

    def __init__(
        self,
        inner: SimSource,
        config: MarkingsSection,
        marking_map: MarkingMap,
        rng: np.random.Generator,
        *,
        surface: Surface | None = None,
        drift: Drift | None = None,
    ) -> None:
        super().__init__(inner)
        self.config = config
        self.marking_map = marking_map
        self.rng = rng
        self.surface = Surface() if surface is None else surface
        self.drift = Drift() if drift is None else drift
        self.reports: list[MarkingReport] = []

    def frames(self) -> Iterator[Frame]:
        """The inner source's frames, each after its scan's localisation step."""
        odometry: Pose | None = None
        localiser: Localiser | None = None
        last: tuple[float, Pose] | None = None
        for frame in self.upstream.frames():
            if frame.scan is not None and frame.pose is not None:
                truth, stamp = frame.pose, frame.scan.stamp_s
                if last is None or localiser is None or odometry is None:
                    odometry = truth
                    localiser = Localiser(truth, self.marking_map, self.config)
                else:
                    delta = self.drift.increment(relative(last[1], truth), stamp - last[0])
                    odometry = compose(odometry, delta)
                    localiser.predict(delta)
                last = (stamp, truth)
                scan, _ = ring_scan(
                    self.config, truth, self.marking_map, self.surface, self.rng, stamp_s=stamp
                )
                found = detect_markings(scan, self.config)
                correction = localiser.update(*found.feature_points())
                self.reports.append(
                    MarkingReport(
                        stamp,
                        truth,
                        odometry,
                        localiser.pose,
                        correction,
                        len(found.lines),
                        len(found.arcs),
                    )
                )
            yield frame

    def summary(self) -> str:
        """One line for a run's report: scans localised, corrections accepted, and the final
        and worst position error of dead reckoning alone and corrected [m]."""
        if not self.reports:
            return "markings: no scan localised"
        odo = [r.error_m(r.odometry_pose, r.true_pose) for r in self.reports]
        cor = [r.error_m(r.corrected_pose, r.true_pose) for r in self.reports]
        n_ok = sum(r.correction.accepted for r in self.reports)
        return (
            f"markings: {n_ok} of {len(self.reports)} scans corrected; position error "
            f"odometry only {odo[-1]:.3f} m (max {max(odo):.3f}), corrected {cor[-1]:.3f} m "
            f"(max {max(cor):.3f}); a localisation aid, not read by the safety chain"
        )


def markings_beside(config: SafecaseConfig, sim: Simulation) -> MarkingsSource:
    """``sim`` in closed loop with the apron's markings (:func:`apron_markings`) localised
    beside it (``safecase run --markings``); the ring scans' noise is seeded by the run's seed
    and nothing else, so the simulator's own streams are unchanged."""
    rng = np.random.default_rng([sim.seed, 25])
    return MarkingsSource(SimSource(sim), config.markings, apron_markings(), rng)
