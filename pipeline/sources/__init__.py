"""Every way a frame arrives, behind one protocol: serial scanners, recorded logs, the simulator.

A source has a ``name``, says whether it is ``live`` (a real clock: cycles are charged their
measured time) and yields :class:`~pipeline.types.Frame` objects from ``frames()``: the scan,
the robot's odometry pose when the source has it, optional thermal and radar detections, a
serial link's health, the route when the source knows it. A closed-loop source (the simulator)
also takes the runtime's command. The runtime runs any of them through one loop
(:func:`safety.run.run`).

- :mod:`.serial`: RPLIDAR and SCIP 2.0 codecs, the pyserial driver, pty emulators, faults
  (:class:`~.serial.source.SerialSource`, :class:`~.serial.source.EmulatedSource`);
- :mod:`.logs`: ROS 1 / ROS 2 bags and MCAP (rosbags), CARMEN, BreezySLAM
  (:class:`~.logs.source.LogSource`);
- :mod:`.sim`: the simulator (:class:`~.sim.source.SimSource`).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol, runtime_checkable

from pipeline.types import Frame

__all__ = ["ClosedLoopSource", "FrameSource"]


@runtime_checkable
class FrameSource(Protocol):
    """Anything that yields stamped frames (module docstring)."""

    @property
    def name(self) -> str: ...

    @property
    def live(self) -> bool: ...

    def frames(self) -> Iterator[Frame]: ...


@runtime_checkable
class ClosedLoopSource(FrameSource, Protocol):
    """A source whose robot follows the runtime's commands (the simulator)."""

    def command(self, speed_mps: float, at_s: float) -> None: ...
