"""A thermal camera in the simulator: person detections from the ground truth (SR-FUS-*).

Fusion needs thermal detections to fuse; the simulator knows where its persons are, so a
camera that sees every person (with position noise, and optionally late) is a few lines over
the ground truth of a scan.
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.sim.objects import ObjectKind
from pipeline.sim.truth import KIND_NAMES, ScanTruth
from pipeline.types import ThermalDetections

__all__ = ["thermal_from_truth"]


def thermal_from_truth(
    truth: ScanTruth,
    rng: np.random.Generator,
    *,
    delay_s: float = 0.0,
    noise_std_m: float = 0.1,
    confidence: float = 0.9,
) -> ThermalDetections:
    """Thermal detections of the simulated persons, in the robot frame at ``truth.stamp_s``.

    Positions get Gaussian noise (``noise_std_m``); every detection is stamped ``delay_s``
    before the scan (a late or stale camera frame).
    """
    person = KIND_NAMES.index(ObjectKind.PERSON.value)
    keep = truth.kind == person
    x, y, yaw = (float(v) for v in truth.ego_pose)
    dx, dy = truth.x_m[keep] - x, truth.y_m[keep] - y
    c, s = math.cos(yaw), math.sin(yaw)
    n = int(np.count_nonzero(keep))
    return ThermalDetections(
        stamp_s=np.full(n, truth.stamp_s - delay_s),
        x_m=c * dx + s * dy + rng.normal(0.0, noise_std_m, n),
        y_m=-s * dx + c * dy + rng.normal(0.0, noise_std_m, n),
        confidence=np.full(n, confidence),
    )
