"""Map matching of detected marking points: a pose correction with its quality (SR-MRK-3).

The points of the fitted markings (robot frame) within ``match_max_range_m`` of the robot (a
farther beam's footprint is long along the ray, and a stripe across the ray smears along it by
a third of that) are placed in the map with the pose to be
corrected and aligned to the stored map's centre lines (:class:`~pipeline.sensors.marking_map.
MarkingMap`) by Gauss-Newton on point-to-line distances: each iteration pairs every point with
its nearest centre line (pairs farther than ``match_gate_m`` are left out), linearises the
residual ``n . (R(dyaw) (p - c) + c + t - q)`` about the current correction (``c`` the robot's
position, so a yaw correction turns the points about the robot, not about the map's origin) and
solves the normal equations. The yaw column is scaled by the points' RMS lever arm so the
three directions are measured alike; a direction whose information per pair is below
``min_information`` (along a single straight stripe, say) is not observable and is left
uncorrected rather than guessed.

The correction is a localisation aid: it is reported, never fed to the perception or safety
chain (SR-MRK-4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import MarkingsSection
from pipeline.frames import to_child, to_parent
from pipeline.sensors.marking_map import MarkingMap
from pipeline.types import FloatArray, Pose

__all__ = ["Localiser", "PoseCorrection", "compose", "corrected", "match_to_map", "relative"]


@dataclass(frozen=True, slots=True)
class PoseCorrection:
    """What map matching found: the corrected pose is ``(x + dx_m, y + dy_m, yaw + dyaw_rad)``
    (map frame). ``n_pairs``: points within the gate of a centre line after the last step;
    ``rms_m``: their RMS distance; ``information``: the eigenvalues (ascending) of the scaled
    information per pair; ``n_observable``: how many directions were corrected; ``accepted``:
    whether the correction passed its gates, else all three are zero and ``reason`` says why."""

    dx_m: float
    dy_m: float
    dyaw_rad: float
    n_pairs: int
    rms_m: float
    information: tuple[float, float, float]
    n_observable: int
    accepted: bool
    reason: str = ""


def corrected(pose: Pose, correction: PoseCorrection) -> Pose:
    """``pose`` with ``correction`` applied (the identity for a rejected one)."""
    if not correction.accepted:
        return pose
    return (
        pose[0] + correction.dx_m,
        pose[1] + correction.dy_m,
        pose[2] + correction.dyaw_rad,
    )


def _rejected(n: int, rms: float, info: tuple[float, float, float], why: str) -> PoseCorrection:
    return PoseCorrection(0.0, 0.0, 0.0, n, rms, info, 0, False, why)


def match_to_map(
    x_m: FloatArray,
    y_m: FloatArray,
    pose: Pose,
    marking_map: MarkingMap,
    config: MarkingsSection,
) -> PoseCorrection:
    """The correction of ``pose`` that best aligns the robot-frame marking points ``(x_m, y_m)``
    with ``marking_map`` (module docstring): points farther than ``match_max_range_m`` from the
    robot are left out (a far beam's footprint smears a stripe along the ray); gated by
    ``min_match_points``,
    ``max_match_rms_m`` and ``max_correction_m``."""
    zero = (0.0, 0.0, 0.0)
    near_robot = np.hypot(x_m, y_m) <= config.match_max_range_m
    x_m, y_m = x_m[near_robot], y_m[near_robot]
    if x_m.shape[0] < config.min_match_points:
        return _rejected(0, math.nan, zero, f"{x_m.shape[0]} marking points")
    px, py = to_parent(pose, np.asarray(x_m, float), np.asarray(y_m, float))
    cx, cy = pose[0], pose[1]
    vx0, vy0 = px - cx, py - cy
    lever = max(float(np.sqrt(np.mean(vx0 * vx0 + vy0 * vy0))), 1.0)
    t = np.zeros(2)
    yaw = 0.0
    info = np.zeros(3)
    n_obs = 0
    for _ in range(config.match_iterations):
        vx, vy = to_parent((0.0, 0.0, yaw), vx0, vy0)
        qx, qy = cx + t[0] + vx, cy + t[1] + vy
        near = marking_map.nearest(qx, qy)
        pair = near.distance_m <= config.match_gate_m
        m = int(pair.sum())
        if m < config.min_match_points:
            return _rejected(m, math.nan, zero, f"{m} points within the gate")
        nx, ny = near.nx[pair], near.ny[pair]
        res = nx * (qx[pair] - near.x_m[pair]) + ny * (qy[pair] - near.y_m[pair])
        jac = np.stack([nx, ny, (nx * -vy[pair] + ny * vx[pair]) / lever], axis=1)
        h = jac.T @ jac / m
        g = jac.T @ res / m
        w, v = np.linalg.eigh(h)
        keep = w >= config.min_information
        info, n_obs = w, int(keep.sum())
        step = -(v[:, keep] @ ((v[:, keep].T @ g) / w[keep]))
        t += step[:2]
        yaw += float(step[2]) / lever
    qx, qy = to_parent((cx + float(t[0]), cy + float(t[1]), yaw), vx0, vy0)
    near = marking_map.nearest(qx, qy)
    pair = near.distance_m <= config.match_gate_m
    m = int(pair.sum())
    rms = float(np.sqrt(np.mean(near.distance_m[pair] ** 2))) if m else math.nan
    info_t = (float(info[0]), float(info[1]), float(info[2]))
    if m < config.min_match_points:
        return _rejected(m, rms, info_t, f"{m} points within the gate")
    if not rms <= config.max_match_rms_m:
        return _rejected(m, rms, info_t, f"RMS residual {rms:.3f} m")
    size = max(math.hypot(t[0], t[1]), abs(yaw) * lever)
    if size > config.max_correction_m:
        return _rejected(m, rms, info_t, f"correction of {size:.2f} m")
    return PoseCorrection(float(t[0]), float(t[1]), yaw, m, rms, info_t, n_obs, True)


def compose(pose: Pose, delta: Pose) -> Pose:
    """``pose`` moved by ``delta`` given in its own (robot) frame: odometry's increment."""
    x, y = to_parent(pose, delta[0], delta[1])
    return (x, y, pose[2] + delta[2])


def relative(start: Pose, end: Pose) -> Pose:
    """The increment, in ``start``'s own frame, that :func:`compose` turns into ``end``."""
    x, y = to_child(start, end[0], end[1])
    return (x, y, end[2] - start[2])


class Localiser:
    """The simplest estimator that uses the correction (SR-MRK-3): dead reckoning on odometry
    increments (:meth:`predict`), and after each scan the accepted map-matching correction
    applied with ``gain`` (:meth:`update`; 1 takes it whole). Its pose is a report for a
    localisation consumer; nothing in the safety chain reads it (SR-MRK-4)."""

    def __init__(
        self, start: Pose, marking_map: MarkingMap, config: MarkingsSection, gain: float = 1.0
    ) -> None:
        if not 0.0 < gain <= 1.0:
            raise ValueError(f"Localiser: gain must be in (0, 1], got {gain}")
        self.pose: Pose = start
        self.marking_map = marking_map
        self.config = config
        self.gain = gain

    def predict(self, delta: Pose) -> Pose:
        """Dead reckoning by one odometry increment."""
        self.pose = compose(self.pose, delta)
        return self.pose

    def update(self, x_m: FloatArray, y_m: FloatArray) -> PoseCorrection:
        """Match the scan's marking points (robot frame) and apply an accepted correction."""
        found = match_to_map(x_m, y_m, self.pose, self.marking_map, self.config)
        if found.accepted:
            g = self.gain
            x, y, yaw = self.pose
            self.pose = (x + g * found.dx_m, y + g * found.dy_m, yaw + g * found.dyaw_rad)
        return found
