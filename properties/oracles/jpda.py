"""Stone Soup's JPDA, PDA hypothesiser and PDA updater on one cluster of tracks (test-only
oracle of SR-TRK-8).

The tracks are handed over already predicted to the detections' time (a constant-velocity
transition over zero time is the identity with no process noise), so Stone Soup's prediction
step leaves them as they are and only its association and update are compared. The gate
probability is the one whose chi-square quantile is our Mahalanobis gate.
"""

from __future__ import annotations

import datetime
import math

import numpy as np
from stonesoup.dataassociator.probability import JPDA
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import (
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.types.track import Track
from stonesoup.updater.probability import PDAUpdater

from pipeline.types import FloatArray

__all__ = ["stonesoup_jpda"]

_T0 = datetime.datetime(2026, 1, 1)


def stonesoup_jpda(
    x: FloatArray,
    p: FloatArray,
    z_m: FloatArray,
    measurement_std_m: float,
    detection_prob: float,
    gate_chi2: float,
    clutter_density_per_m2: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Association probabilities (k, d + 1; column 0 missed, zero where not gated) and the
    posterior states (k, 4) and covariances (k, 4, 4) Stone Soup gives the predicted tracks
    ``x``, ``p`` with detections ``z_m`` (d, 2)."""
    model = LinearGaussian(
        ndim_state=4, mapping=(0, 1), noise_covar=np.eye(2) * measurement_std_m**2
    )
    transition = CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(0.0), ConstantVelocity(0.0)]
    )
    updater = PDAUpdater(model)
    hypothesiser = PDAHypothesiser(
        predictor=KalmanPredictor(transition),
        updater=updater,
        clutter_spatial_density=clutter_density_per_m2,
        prob_detect=detection_prob,
        prob_gate=1.0 - math.exp(-0.5 * gate_chi2),
    )
    tracks = [
        Track([GaussianState(xi.reshape(4, 1), pi, timestamp=_T0)])
        for xi, pi in zip(x, p, strict=True)
    ]
    detections = [Detection(zi.reshape(2, 1), timestamp=_T0, measurement_model=model) for zi in z_m]
    index = {id(det): j for j, det in enumerate(detections)}
    result = JPDA(hypothesiser).associate(set(tracks), set(detections), _T0)
    k, d = x.shape[0], z_m.shape[0]
    beta = np.zeros((k, d + 1))
    x_post = np.zeros((k, 4))
    p_post = np.zeros((k, 4, 4))
    for i, track in enumerate(tracks):
        hypotheses = result[track]
        for hyp in hypotheses:
            col = 0 if not hyp else index[id(hyp.measurement)] + 1
            beta[i, col] = float(hyp.probability)
        update = updater.update(hypotheses)
        x_post[i] = np.asarray(update.state_vector, dtype=np.float64).ravel()
        p_post[i] = np.asarray(update.covar, dtype=np.float64)
    return beta, x_post, p_post
