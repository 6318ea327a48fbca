"""Cycle scenes made by hand, for the tests of the Foxglove recording and its reader.

A scene of a cycle that saw nothing: no scan, points, tracks, envelopes, path or costmap, a
PROCEED at 1 m/s with no reasons; a test gives it the pose, stamp, verdicts and record it needs
and adds what it checks.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.types import Action
from safety.foxglove_scene import CycleScene

__all__ = ["empty_scene"]


def empty_scene(**fields: Any) -> CycleScene:
    """A scene with nothing seen (module docstring), ``fields`` set on it."""
    empty: dict[str, Any] = {
        "stamp_s": 0.0,
        "robot_pose": (0.0, 0.0, 0.0),
        "mount": (0.0, 0.0, 0.0),
        "scan": None,
        "points_xy_m": np.zeros((2, 0)),
        "point_labels": np.zeros(0, dtype=np.int64),
        "track_id": np.zeros(0, dtype=np.int64),
        "track_xy_m": np.zeros((2, 0)),
        "track_v_mps": np.zeros((2, 0)),
        "track_radius_m": np.zeros(0),
        "track_class": (),
        "envelopes": (),
        "envelope_tier": np.zeros(0, dtype=np.int64),
        "envelope_track": np.zeros(0, dtype=np.int64),
        "path_xy_m": np.zeros((0, 2)),
        "occupied": None,
        "costmap_origin_m": (0.0, 0.0),
        "costmap_resolution_m": 1.0,
        "action": Action.PROCEED,
        "speed_mps": 1.0,
        "reasons": (),
        "verdicts": (),
        "record": {},
    }
    return CycleScene(**(empty | fields))
