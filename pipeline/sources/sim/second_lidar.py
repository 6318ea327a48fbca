"""A second scanner on the simulated robot (SR-LID-1, SR-LID-3, SR-LID-4).

:class:`SecondLidarSource` sits beside a closed-loop simulator
(:class:`~pipeline.sources.sim.source.SimSourceBeside`): to each of its frames it adds a
revolution of a second scanner mounted at ``mount`` on the same robot (``scan2.mount_*``), cast
over the same world with the same beam layout and sensor model
(:class:`~pipeline.sources.sim.lidar.Lidar`, from its own generator, so the first scanner's
streams are the same bits with or without it), stamped with the first scan's stamp (the two
scanners synchronised) and carrying the robot's pose at that stamp.

``outages`` are intervals of simulated time [s] in which the second scanner delivers nothing
new: each frame then carries the last revolution it did deliver, which ages as the run goes
on, as a stalled scanner's newest data does (the runtime must leave it out, SR-LID-2). A run
that starts inside an outage carries no second scan until it ends.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Sequence

import numpy as np

from pipeline.sources.sim.lidar import Lidar, LidarSpec
from pipeline.sources.sim.source import SimSource, SimSourceBeside
from pipeline.types import FloatArray, Frame, Pose, SecondScan

__all__ = ["SecondLidarSource"]


class SecondLidarSource(SimSourceBeside):
    """``upstream``'s frames, each with a second scanner's newest revolution (module docstring).
    ``rng`` draws the second scanner's noise; ``outages`` are ``(start_s, end_s)`` intervals."""

    def __init__(
        self,
        upstream: SimSource | SimSourceBeside,
        spec: LidarSpec,
        mount: Pose,
        rng: np.random.Generator,
        *,
        outages: Sequence[tuple[float, float]] = (),
    ) -> None:
        super().__init__(upstream)
        for start, end in outages:
            if not start < end:
                raise ValueError(
                    f"SecondLidarSource: outage ({start}, {end}) must have start < end"
                )
        self.lidar = Lidar(spec, rng)
        self.mount = mount
        self.outages = tuple(outages)
        self.delivered = 0

    def _out(self, stamp_s: float) -> bool:
        return any(start <= stamp_s < end for start, end in self.outages)

    def frames(self) -> Iterator[Frame]:
        """The upstream source's frames with the second scanner's newest revolution added."""
        sim = self.inner.sim
        ego = dataclasses.replace(sim.ego_spec, mount=self.mount)

        def scanner_poses(t_s: FloatArray) -> FloatArray:
            return ego.scanner_poses(sim.ego.poses_at(t_s))

        newest: SecondScan | None = None
        for frame in self.upstream.frames():
            if frame.scan is not None and not self._out(frame.scan.stamp_s):
                stamp = frame.scan.stamp_s
                scan, _ = self.lidar.scan(
                    sim.world,
                    scanner_poses,
                    stamp,
                    seq=frame.scan.seq,
                    source=f"sim:{sim.name}:{sim.seed}:second",
                )
                newest = SecondScan(scan, frame.pose)
                self.delivered += 1
            yield dataclasses.replace(frame, second=newest)
