"""The batched Kalman filter where the mutation campaign found it unwatched (SR-TRK-3, SR-AVL-7).

Three gaps (SR-EVD-6, docs/findings/mutation.md): initial covariances were only ever built
with unit standard deviations; a batch whose tracks have different time steps (a track
re-observed after a miss beside one seen every cycle) was never predicted; and re-acquisition
after a gap was never compared with a reference filter on a position covariance with
correlation. The references are filterpy's ``KalmanFilter`` and the transition matrix written
out here.
"""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from pipeline.track.kalman import initiate, predict, process_noise, reacquire

KALMAN = ["pipeline/track/kalman.py"]


def _transition(dt_s: float) -> np.ndarray:
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt_s
    return f


@pytest.mark.requirement("SR-TRK-3", code=KALMAN)
def test_new_tracks_start_with_the_variances_of_the_given_standard_deviations() -> None:
    x, p = initiate(np.array([[1.0, -2.0], [3.5, 0.25]]), 0.3, 0.7)
    np.testing.assert_array_equal(x, [[1.0, -2.0, 0.0, 0.0], [3.5, 0.25, 0.0, 0.0]])
    for cov in p:
        np.testing.assert_array_equal(cov, np.diag([0.3 * 0.3, 0.3 * 0.3, 0.7 * 0.7, 0.7 * 0.7]))


@pytest.mark.requirement("SR-TRK-3", code=KALMAN)
def test_tracks_with_different_time_steps_are_each_predicted_by_their_own() -> None:
    rng = np.random.default_rng(3)
    n, accel = 3, 1.2
    x = rng.normal(size=(n, 4))
    m = rng.normal(size=(n, 4, 4))
    p = np.matmul(m, np.swapaxes(m, 1, 2)) + 0.1 * np.eye(4)
    for dt in (np.array([0.1, 0.25, 0.1]), np.array([0.1, 0.1, 0.1])):
        x_new, p_new = predict(x, p, dt, accel)
        for k in range(n):
            f, q = _transition(float(dt[k])), process_noise(dt[k : k + 1], accel)[0]
            np.testing.assert_allclose(x_new[k], f @ x[k], rtol=0, atol=1e-12)
            np.testing.assert_allclose(p_new[k], f @ p[k] @ f.T + q, rtol=0, atol=1e-12)


@pytest.mark.requirement("SR-AVL-7", code=KALMAN)
def test_reacquisition_updates_the_position_as_filterpy_does_and_keeps_the_velocity() -> None:
    rng = np.random.default_rng(11)
    n = 4
    x = rng.normal(size=(n, 4))
    m = rng.normal(size=(n, 4, 4))
    p = np.matmul(m, np.swapaxes(m, 1, 2)) + 0.05 * np.eye(4)  # correlated positions
    assert np.all(np.abs(p[:, 0, 1]) > 1e-3)
    z = x[:, :2] + rng.normal(size=(n, 2))
    std = np.array([0.2, 0.5, 1.0, 2.0])
    widen = np.array([0.0, 0.3, 1.0, 0.1])
    x_new, p_new = reacquire(x, p, z, std, widen)
    for k in range(n):
        kf = KalmanFilter(dim_x=2, dim_z=2)
        kf.x = x[k, :2].copy()
        kf.P = p[k, :2, :2].copy()
        kf.H = np.eye(2)
        kf.R = std[k] ** 2 * np.eye(2)
        kf.update(z[k])
        np.testing.assert_allclose(x_new[k, :2], kf.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(p_new[k, :2, :2], kf.P, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(x_new[k, 2:], x[k, 2:])
        np.testing.assert_allclose(
            p_new[k, 2:, 2:], p[k, 2:, 2:] + widen[k] ** 2 * np.eye(2), rtol=0, atol=1e-12
        )
        np.testing.assert_array_equal(p_new[k, :2, 2:], 0.0)
