"""Frozen data passed between the stages of the data path (struct of arrays, units in names).

Each hop of ``serial/sim -> Scan -> clusters -> tracks -> classes -> envelopes -> Command`` has
one type here. Arrays are made read-only on construction so a stage cannot modify what an
earlier stage (or the audit log) still holds.
"""

from __future__ import annotations

from pipeline.types.core import (
    Action,
    BoolArray,
    Command,
    FloatArray,
    IntArray,
    Scan,
    freeze_fields,
    frozen_array,
)
from pipeline.types.drivers import DriverHealth, DriverState
from pipeline.types.fusion import FusedTracks, FusionCounts, RadarDetections, ThermalDetections
from pipeline.types.geometry import ConvexPolygons, SweptPathReport
from pipeline.types.perception import (
    Classification,
    Envelopes,
    PredictionMode,
    Predictions,
    TrackFeatures,
)
from pipeline.types.tracking import (
    ClusterCounts,
    Clusters,
    DropCounts,
    ScanPoints,
    Tracks,
    TrackStatus,
)

__all__ = [
    "Action",
    "BoolArray",
    "Classification",
    "ClusterCounts",
    "Clusters",
    "Command",
    "ConvexPolygons",
    "DriverHealth",
    "DriverState",
    "DropCounts",
    "Envelopes",
    "FloatArray",
    "FusedTracks",
    "FusionCounts",
    "IntArray",
    "PredictionMode",
    "Predictions",
    "RadarDetections",
    "Scan",
    "ScanPoints",
    "SweptPathReport",
    "ThermalDetections",
    "TrackFeatures",
    "TrackStatus",
    "Tracks",
    "freeze_fields",
    "frozen_array",
]
