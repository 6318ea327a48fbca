"""The simulator as a source of frames, closed loop: the runtime's command drives the robot.

:class:`SimSource` yields one :class:`~pipeline.types.Frame` per scan of a
:class:`~pipeline.sources.sim.simulation.Simulation`: the scan as its revolution completes, the
robot's pose at the scan's stamp (its odometry, exact in simulation), its route and how far
along it the robot is, and optionally thermal detections of the simulated persons. A scan that
arrives while the previous cycle still runs waits for it (``received_s`` is the later of the
two); :meth:`SimSource.command` takes the runtime's speed at the decision time, and the robot
follows it after its actuation latency (SR-RUN-1, SR-SIM-5).

A run through the runtime may last hours, so the source puts its simulation on bounded
retention (:data:`~pipeline.sources.sim.simulation.BOUNDED`: no frames kept, a thinned ego log
and separation record) unless told otherwise: its memory and per-cycle cost stay flat over
the run (SR-RUN-5), and its scans are the same bits as under full retention.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from pipeline.sources.sim.simulation import BOUNDED, Retention, SimResult, Simulation
from pipeline.sources.sim.thermal import thermal_from_truth
from pipeline.types import Frame

__all__ = ["SimSource", "SimSourceBeside"]


class SimSource:
    """Frames of ``sim`` in closed loop (module docstring).

    ``thermal_rng``, when given, adds thermal detections of every simulated person to each
    frame (:func:`~pipeline.sources.sim.thermal.thermal_from_truth`, stamped with the scan).
    ``retention`` (default bounded) is applied to ``sim``, which must not have started; None
    leaves the simulation's own.
    """

    live = False

    def __init__(
        self,
        sim: Simulation,
        thermal_rng: np.random.Generator | None = None,
        *,
        retention: Retention | None = BOUNDED,
    ) -> None:
        if retention is not None and retention != sim.retention:
            sim.retain(retention)
        self.sim = sim
        self.thermal_rng = thermal_rng
        self._busy_until_s = -math.inf

    @property
    def name(self) -> str:
        """The scenario's name."""
        return self.sim.name

    @property
    def n_frames(self) -> int:
        """How many scans the run holds."""
        return self.sim.n_scans

    def frames(self) -> Iterator[Frame]:
        """One frame per scan until the run ends (or stops at a contact)."""
        sim = self.sim
        route = sim.ego_spec.route.points_m
        sim.command(sim.ego_spec.initial_speed_mps)
        while (step := sim.next_frame()) is not None:
            at = sim.ego.poses_at(np.array([step.scan.stamp_s]))[0]
            thermal = None
            if self.thermal_rng is not None:
                thermal = thermal_from_truth(step.truth, self.thermal_rng)
            yield Frame(
                step.scan,
                max(step.observation.stamp_s, self._busy_until_s),
                pose=(float(at[0]), float(at[1]), float(at[2])),
                thermal=thermal,
                route_m=route,
                route_arc_m=sim.ego.arc_m,
            )

    def command(self, speed_mps: float, at_s: float) -> None:
        """The runtime's command, issued at ``at_s`` on the simulated clock [s]."""
        self.sim.ego.command(speed_mps, at_s)
        self._busy_until_s = at_s

    def result(self) -> SimResult:
        """The run so far: contacts, separations, the robot's log."""
        return self.sim.result()


class SimSourceBeside:
    """A closed-loop simulator source with another sensor's work done beside it (a second
    scanner, the camera and radar, the microphone array, the marking localisation): the
    simulator's name, length, commands and result, while a subclass's :meth:`frames` adds what
    its sensor found to ``upstream``'s frames.

    ``upstream`` is the simulator's own source or another source beside it, so that sensors
    compose one on top of the other (:func:`pipeline.sources.sim.rig.sim_source`); ``inner`` is
    always the simulator's own :class:`SimSource` underneath."""

    live = False

    def __init__(self, upstream: SimSource | SimSourceBeside) -> None:
        self.upstream = upstream
        self.inner: SimSource = upstream if isinstance(upstream, SimSource) else upstream.inner

    @property
    def name(self) -> str:
        """The inner source's name."""
        return self.inner.name

    @property
    def n_frames(self) -> int:
        """The inner source's scan count."""
        return self.inner.n_frames

    def frames(self) -> Iterator[Frame]:
        """The upstream source's frames, unchanged (a subclass adds its sensor's work)."""
        return self.upstream.frames()

    def command(self, speed_mps: float, at_s: float) -> None:
        """The runtime's command, passed to the inner source."""
        self.inner.command(speed_mps, at_s)

    def result(self) -> SimResult:
        """The inner run's result."""
        return self.inner.result()
