"""Where scans come from: serial devices, the emulator, the simulator, ROS bags, logs.

Every source is an iterable of :class:`pipeline.types.Scan`, so consumers never know which
one they read. Readers for recorded logs live in ``pipeline.sources.logs``; the serial
transport in ``pipeline.drivers``; the simulator in ``pipeline.sim``.
"""

from __future__ import annotations

from collections.abc import Iterable

from pipeline.types import Scan

ScanSource = Iterable[Scan]

__all__ = ["ScanSource"]
