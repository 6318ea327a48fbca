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
from pipeline.types.frame import Frame, Pose, SecondScan
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
    DROPPED_LABEL,
    NOISE_LABEL,
    ClusterCounts,
    Clusters,
    CycleCounts,
    Detections,
    DropCounts,
    Partition,
    ScanPoints,
    SoftAssociation,
    TrackerError,
    Tracks,
    TrackStatus,
)

__all__ = [
    "DROPPED_LABEL",
    "NOISE_LABEL",
    "Action",
    "BoolArray",
    "Classification",
    "ClusterCounts",
    "Clusters",
    "Command",
    "ConvexPolygons",
    "CycleCounts",
    "Detections",
    "DriverHealth",
    "DriverState",
    "DropCounts",
    "Envelopes",
    "FloatArray",
    "Frame",
    "FusedTracks",
    "FusionCounts",
    "IntArray",
    "Partition",
    "Pose",
    "PredictionMode",
    "Predictions",
    "RadarDetections",
    "Scan",
    "ScanPoints",
    "SecondScan",
    "SoftAssociation",
    "SweptPathReport",
    "ThermalDetections",
    "TrackFeatures",
    "TrackStatus",
    "TrackerError",
    "Tracks",
    "freeze_fields",
    "frozen_array",
]
