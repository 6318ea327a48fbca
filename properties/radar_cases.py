"""Kinematics for radar properties (SR-FUS-7, SR-SIM-8): where a robot moving at a constant
twist is after a while, exactly, so that range rates can be measured by finite differences of
the true geometry rather than by the formula under test."""

from __future__ import annotations

import math

from pipeline.types.sensors import Twist

__all__ = ["pose_at"]


def pose_at(
    pose: tuple[float, float, float], twist: Twist, t_s: float
) -> tuple[float, float, float]:
    """The robot's pose after ``t_s`` at a constant body-frame twist: the exact arc, whose
    chord is the body velocity turned by half the heading change and scaled by
    ``t sin(h) / h`` with ``h = w t / 2`` (stable for any yaw rate, 0 included)."""
    x, y, yaw = pose
    half = 0.5 * twist.yaw_rate_rps * t_s
    scale = t_s * (math.sin(half) / half if half != 0.0 else 1.0)
    c, s = math.cos(yaw + half), math.sin(yaw + half)
    dx, dy = twist.vx_mps * scale, twist.vy_mps * scale
    return x + c * dx - s * dy, y + s * dx + c * dy, yaw + 2.0 * half
