"""Rigid 2-D transforms: the one home of the rotation between robot, tracking and sensor frames.

A *pose* ``(x_m, y_m, yaw_rad)`` places a child frame in its parent: the child's origin at
``(x_m, y_m)`` of the parent, its x axis turned ``yaw_rad`` counter-clockwise from the
parent's. The frames of the data path:

- the *robot* frame (x forward, y left), in which a scanner mounted at the robot's centre
  reports its points and the thermal camera and radar their detections;
- the *tracking* frame (odometry), in which the tracker keeps its tracks: the robot's pose at a
  scan's stamp places the robot frame in it (the identity for a robot that does not move, or a
  source without odometry: tracking then happens in the robot frame).

Every function is vectorised: over points, and over poses when the pose's components are
arrays (one pose per sample of a trajectory, broadcast against the points). The arithmetic
order is fixed here (``x0 + c x - s y``) so that a point moved the same way lands on the same
bits wherever it is moved; a pose given as numpy values is turned with numpy's ``cos`` and
``sin``, one of Python floats with :mod:`math`'s.

>>> to_parent((1.0, 2.0, 0.0), np.array([0.5]), np.array([0.0]))
(array([1.5]), array([2.]))
"""

from __future__ import annotations

import math
from typing import Any, TypeVar

import numpy as np

from pipeline.errors import SafecaseError
from pipeline.types import Pose

__all__ = [
    "IDENTITY",
    "AnyPose",
    "FrameError",
    "Pose",
    "checked_pose",
    "inverse",
    "is_identity",
    "to_child",
    "to_parent",
]

IDENTITY: Pose = (0.0, 0.0, 0.0)

Coords = TypeVar("Coords", float, "np.ndarray")
# A pose whose components are floats or arrays of poses (broadcast against the points).
AnyPose = tuple[Any, Any, Any]


class FrameError(SafecaseError, ValueError):
    """A pose that is not three finite numbers ``(x_m, y_m, yaw_rad)``."""


def checked_pose(pose: object) -> Pose:
    """``pose`` as three finite floats, or :class:`FrameError` naming what was given."""
    try:
        x, y, yaw = (float(v) for v in pose)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise FrameError(
            f"pose {pose!r}: expected three finite numbers (x_m, y_m, yaw_rad)"
        ) from None
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw)):
        raise FrameError(f"pose {pose!r}: expected three finite numbers (x_m, y_m, yaw_rad)")
    return (x, y, yaw)


def is_identity(pose: Pose) -> bool:
    """True for the pose that moves nothing (exactly zero offset and yaw)."""
    return pose == IDENTITY


def _cos_sin(yaw: Any) -> tuple[Any, Any]:
    if isinstance(yaw, np.ndarray | np.generic):
        return np.cos(yaw), np.sin(yaw)
    return math.cos(yaw), math.sin(yaw)


def to_parent(pose: AnyPose, x_m: Coords, y_m: Coords) -> tuple[Coords, Coords]:
    """Points given in the child frame placed by ``pose``, expressed in its parent [m]."""
    x0, y0, yaw = pose
    c, s = _cos_sin(yaw)
    return x0 + c * x_m - s * y_m, y0 + s * x_m + c * y_m


def to_child(pose: AnyPose, x_m: Coords, y_m: Coords) -> tuple[Coords, Coords]:
    """Points given in the parent, expressed in the child frame placed by ``pose`` [m]."""
    x0, y0, yaw = pose
    c, s = _cos_sin(yaw)
    dx, dy = x_m - x0, y_m - y0
    return c * dx + s * dy, -s * dx + c * dy


def inverse(pose: Pose) -> Pose:
    """The pose of the parent frame in the child frame placed by ``pose``."""
    x, y, yaw = pose
    c, s = math.cos(-yaw), math.sin(-yaw)
    return (-(c * x - s * y), -(s * x + c * y), -yaw)
