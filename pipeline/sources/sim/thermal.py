"""A thermal camera in the simulator: person detections from the ground truth (SR-FUS-*).

Fusion needs thermal detections to fuse; the simulator knows where its persons are, so a
camera that sees every person (with position noise, and optionally late) is a few lines over
the ground truth of a scan.
"""

from __future__ import annotations

import numpy as np

from pipeline.frames import to_child
from pipeline.sources.sim.objects import ObjectKind
from pipeline.sources.sim.truth import KIND_NAMES, ScanTruth
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
    pose = (float(truth.ego_pose[0]), float(truth.ego_pose[1]), float(truth.ego_pose[2]))
    x_m, y_m = to_child(pose, truth.x_m[keep], truth.y_m[keep])
    n = int(np.count_nonzero(keep))
    return ThermalDetections(
        stamp_s=np.full(n, truth.stamp_s - delay_s),
        x_m=x_m + rng.normal(0.0, noise_std_m, n),
        y_m=y_m + rng.normal(0.0, noise_std_m, n),
        confidence=np.full(n, confidence),
    )
