"""Constant-velocity Kalman filter over all tracks at once (requirements SR-TRK-3, SR-TRK-6).

State ``[x_m, y_m, vx_mps, vy_mps]`` per track, measurement the cluster centroid ``[x_m, y_m]``.
Process noise is the discrete white-noise acceleration model (variance
``accel_std_mps2**2``), measurement noise ``measurement_std_m**2 * I``. The arithmetic is that
of filterpy's ``KalmanFilter`` (predict ``P = F P F' + Q``; update with the Joseph form
``P = (I - K H) P (I - K H)' + K R K'``), batched over a leading track axis, so the two agree to
rounding (checked to 1e-9 by a property). Covariances are symmetrized after each step, which
changes them by rounding only and keeps them exactly symmetric; the Joseph form keeps them
positive definite.
"""

from __future__ import annotations

import numpy as np

from pipeline.types import FloatArray

__all__ = [
    "initiate",
    "innovation",
    "largest_std",
    "predict",
    "process_noise",
    "reacquire",
    "update",
]

_H_ROWS = 2


def process_noise(dt_s: FloatArray, accel_std_mps2: float) -> FloatArray:
    """Discrete white-noise acceleration covariance ``Q`` (n, 4, 4) for steps ``dt_s``."""
    var = accel_std_mps2 * accel_std_mps2
    dt2 = dt_s * dt_s
    pp = 0.25 * dt2 * dt2 * var
    pv = 0.5 * dt2 * dt_s * var
    vv = dt2 * var
    q = np.zeros((dt_s.shape[0], 4, 4))
    q[:, 0, 0] = q[:, 1, 1] = pp
    q[:, 0, 2] = q[:, 2, 0] = q[:, 1, 3] = q[:, 3, 1] = pv
    q[:, 2, 2] = q[:, 3, 3] = vv
    return q


def _symmetric(p: FloatArray) -> FloatArray:
    return 0.5 * (p + np.swapaxes(p, 1, 2))


def initiate(
    z_m: FloatArray, measurement_std_m: float, velocity_std_mps: float
) -> tuple[FloatArray, FloatArray]:
    """Initial states and covariances for new tracks at measurements ``z_m`` (n, 2).

    Velocity starts at zero with standard deviation ``velocity_std_mps``; position takes the
    measurement with the measurement's own variance.
    """
    n = z_m.shape[0]
    x = np.zeros((n, 4))
    x[:, :2] = z_m
    p = np.zeros((n, 4, 4))
    p[:, 0, 0] = p[:, 1, 1] = measurement_std_m * measurement_std_m
    p[:, 2, 2] = p[:, 3, 3] = velocity_std_mps * velocity_std_mps
    return x, p


def predict(
    x: FloatArray, p: FloatArray, dt_s: FloatArray, accel_std_mps2: float
) -> tuple[FloatArray, FloatArray]:
    """Predict states ``x`` (n, 4) and covariances ``p`` (n, 4, 4) by ``dt_s`` (n,) seconds.

    ``F P F'`` is formed as two row/column operations (F adds dt times the velocity rows to the
    position rows), which is exactly what the dense product computes with F's 0/1 entries.
    """
    dt = dt_s[:, None]
    x_new = x.copy()
    x_new[:, :2] += dt * x[:, 2:]
    p_new = p.copy()
    p_new[:, :2, :] += dt[:, :, None] * p_new[:, 2:, :]
    p_new[:, :, :2] += dt[:, None, :] * p_new[:, :, 2:]
    if dt_s.shape[0] and dt_s.min() == dt_s.max():
        # The usual cycle: one step for every track, so one Q broadcast over the batch.
        p_new += process_noise(dt_s[:1], accel_std_mps2)
    else:
        p_new += process_noise(dt_s, accel_std_mps2)
    return x_new, _symmetric(p_new)


def innovation(p: FloatArray, measurement_std_m: float) -> tuple[FloatArray, FloatArray]:
    """Innovation covariances ``S = H P H' + R`` (n, 2, 2) and their inverses."""
    s = p[:, :_H_ROWS, :_H_ROWS] + (measurement_std_m * measurement_std_m) * np.eye(_H_ROWS)
    det = s[:, 0, 0] * s[:, 1, 1] - s[:, 0, 1] * s[:, 1, 0]
    s_inv = np.empty_like(s)
    s_inv[:, 0, 0] = s[:, 1, 1] / det
    s_inv[:, 1, 1] = s[:, 0, 0] / det
    s_inv[:, 0, 1] = -s[:, 0, 1] / det
    s_inv[:, 1, 0] = -s[:, 1, 0] / det
    return s, s_inv


def update(
    x: FloatArray, p: FloatArray, z_m: FloatArray, measurement_std_m: float
) -> tuple[FloatArray, FloatArray]:
    """Update states ``x`` (n, 4) and covariances ``p`` with measurements ``z_m`` (n, 2).

    Joseph form with ``H = [I 0]``: ``A = I - K H`` gives ``A P = P - K P[:2, :]`` and
    ``(A P) A' = A P - (A P)[:, :2] K'``, then ``+ r K K'``.
    """
    r = measurement_std_m * measurement_std_m
    _, s_inv = innovation(p, measurement_std_m)
    k = np.matmul(p[:, :, :_H_ROWS], s_inv)
    y = z_m - x[:, :_H_ROWS]
    x_new = x + np.matmul(k, y[:, :, None])[:, :, 0]
    kt = np.swapaxes(k, 1, 2)
    ap = p - np.matmul(k, p[:, :_H_ROWS, :])
    p_new = ap - np.matmul(ap[:, :, :_H_ROWS], kt) + r * np.matmul(k, kt)
    return x_new, _symmetric(p_new)


def reacquire(
    x: FloatArray,
    p: FloatArray,
    z_m: FloatArray,
    position_std_m: FloatArray,
    velocity_widen_mps: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Re-acquire predicted tracks ``x`` (n, 4), ``p`` at measurements ``z_m`` (n, 2) after a gap.

    The position is updated from the position block alone with a measurement standard
    deviation ``position_std_m`` (n,) (the centroid of a view of another side of the object);
    the velocity estimate is kept, its standard deviation widened by ``velocity_widen_mps`` (n,)
    on each axis (added in quadrature), with no position-velocity correlation left. After a long
    gap the correlation that :func:`predict` builds would turn the whole position innovation into
    a velocity, which the measurement cannot tell from a change of view (SR-AVL-7).
    """
    r = (position_std_m * position_std_m)[:, None, None]
    pp = p[:, :_H_ROWS, :_H_ROWS]
    s = pp + r * np.eye(_H_ROWS)
    det = s[:, 0, 0] * s[:, 1, 1] - s[:, 0, 1] * s[:, 1, 0]
    s_inv = np.stack(
        [np.stack([s[:, 1, 1], -s[:, 0, 1]], 1), np.stack([-s[:, 1, 0], s[:, 0, 0]], 1)], 1
    )
    k = np.matmul(pp, s_inv / det[:, None, None])
    a = np.eye(_H_ROWS) - k
    x_new = x.copy()
    x_new[:, :_H_ROWS] += np.matmul(k, (z_m - x[:, :_H_ROWS])[:, :, None])[:, :, 0]
    p_new = np.zeros_like(p)
    p_new[:, :_H_ROWS, :_H_ROWS] = np.matmul(
        np.matmul(a, pp), np.swapaxes(a, 1, 2)
    ) + r * np.matmul(k, np.swapaxes(k, 1, 2))
    widen = velocity_widen_mps * velocity_widen_mps
    p_new[:, _H_ROWS:, _H_ROWS:] = p[:, _H_ROWS:, _H_ROWS:] + widen[:, None, None] * np.eye(2)
    return x_new, _symmetric(p_new)


def largest_std(cov: FloatArray) -> FloatArray:
    """Square root of the largest eigenvalue of each symmetric 2x2 matrix in ``cov`` (n, 2, 2)."""
    a, b, d = cov[:, 0, 0], 0.5 * (cov[:, 0, 1] + cov[:, 1, 0]), cov[:, 1, 1]
    half_trace = 0.5 * (a + d)
    root = np.sqrt(np.maximum(0.25 * (a - d) ** 2 + b * b, 0.0))
    result: FloatArray = np.sqrt(np.maximum(half_trace + root, 0.0))
    return result
