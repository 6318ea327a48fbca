"""The painted markings of the simulated apron stand (#25; SR-MRK-1, SR-MRK-3).

Laid out on the frame of :func:`pipeline.sources.sim.layouts.apron_stand` (the service road
along x at y = 0, 3 m either side; the A320 parked nose-in at x = -8 facing +y), extended along
the road to x = 100 with two more stands. All paint 0.15 m wide:

* the service road's edge lines at y = -3 and y = +3 and its dashed centre line (3 m dashes,
  3 m gaps), x = -20..100;
* stop lines across the road at x = 12, 40 and 70 (where a taxilane crossing would be);
* a taxilane centre line at y = 9;
* at each stand (x0 = -8, 30, 68): a lead-in arc of radius 6 m turning off the taxilane into
  the stand, the lead-in line along +y to the nose position at y = 36, and a 2 m stop bar there.
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.sensors.marking_map import MarkingMap

__all__ = ["STAND_X_M", "apron_markings"]

STAND_X_M = (-8.0, 30.0, 68.0)
_X_RANGE = (-20.0, 100.0)
_ROAD_HALF_M = 3.0
_TAXILANE_Y_M = 9.0
_LEAD_IN_RADIUS_M = 6.0
_NOSE_Y_M = 36.0


def apron_markings(width_m: float = 0.15) -> MarkingMap:
    """The stand's marking map (module docstring)."""
    x0, x1 = _X_RANGE
    segments: list[tuple[float, float, float, float]] = [
        (x0, -_ROAD_HALF_M, x1, -_ROAD_HALF_M),
        (x0, _ROAD_HALF_M, x1, _ROAD_HALF_M),
        (x0, _TAXILANE_Y_M, x1, _TAXILANE_Y_M),
    ]
    for start in np.arange(x0, x1, 6.0):
        segments.append((float(start), 0.0, float(start) + 3.0, 0.0))
    for x in (12.0, 40.0, 70.0):
        segments.append((x, -_ROAD_HALF_M, x, _ROAD_HALF_M))
    arcs: list[tuple[float, float, float, float, float]] = []
    r = _LEAD_IN_RADIUS_M
    for sx in STAND_X_M:
        # From the taxilane at (sx - r, 9) round to (sx, 9 + r), heading +y.
        arcs.append((sx - r, _TAXILANE_Y_M + r, r, -0.5 * math.pi, 0.5 * math.pi))
        segments.append((sx, _TAXILANE_Y_M + r, sx, _NOSE_Y_M))
        segments.append((sx - 1.0, _NOSE_Y_M, sx + 1.0, _NOSE_Y_M))
    return MarkingMap(np.array(segments), np.array(arcs), width_m)
